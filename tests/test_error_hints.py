"""The commands that error messages suggest run as given, paths with spaces included (HaTT's files have them)."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from flowtex.cli import main
from flowtex.errors import FlowtexError
from tests.conftest import REPO

DATA = REPO / "graphs" / "data"


def _run_suggested(message: str, out: Path) -> None:
    """Run the ``flowtex models resample ...`` the message suggests, with OUT.json replaced by ``out``."""
    found = re.search(r"run '(flowtex models resample .*? -o OUT\.json)'", message)
    assert found, message
    argv = shlex.split(found.group(1).replace("OUT.json", shlex.quote(str(out))))
    assert main(argv[1:]) == 0
    assert out.exists()


def test_a_tap_library_at_another_rate(tmp_path: Path) -> None:
    import flowtex

    (tmp_path / "my taps.json").write_bytes((DATA / "synthetic_taps.json").read_bytes())
    (tmp_path / "g.yaml").write_text("flowtex: 1\nname: taps\nrate: 2000\ninputs:\n  in_contact: {}\n  speed: {unit: mm/s}\n"
                                     "nodes:\n  tap: {type: tap_player, params: {library: my taps.json}}\n"
                                     "edges:\n  - in_contact -> tap.in_contact\n  - speed -> tap.incoming_speed\n"
                                     "outputs:\n  force: tap.force\n")
    with pytest.raises(FlowtexError) as err:
        flowtex.load_graph(tmp_path / "g.yaml", tier="dispatch")
    _run_suggested(str(err.value), tmp_path / "taps_2k.json")


def test_a_scene_surface_at_another_rate(tmp_path: Path) -> None:
    from flowtex.scene.file import load_scene
    from flowtex.scene.plan import plan_scene

    (tmp_path / "my surface.json").write_bytes((DATA / "synthetic_texture.json").read_bytes())
    scene = tmp_path / "s.yaml"
    scene.write_text("flowtex: 1\nname: s\nrate: 2000\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\n"
                     "surfaces:\n  a:\n    models: my surface.json\n")
    with pytest.raises(FlowtexError) as err:
        plan_scene(load_scene(scene))
    _run_suggested(str(err.value), tmp_path / "surface_2k.json")
