"""Every example graph (and scene) in graphs/ runs, and its outputs are pinned by a golden file.

Regenerate after an intended change with ``pytest tests/test_examples.py --update-golden``
and review the new files before committing them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flowtex.cli import main

REPO = Path(__file__).resolve().parents[1]
GRAPHS = REPO / "graphs"
GOLDEN = REPO / "tests" / "golden"

# graph file -> (recording it runs on, extra options for the golden check)
EXAMPLES: dict[str, tuple[str, dict]] = {
    "accel_preprocess.yaml": ("data/accel_demo.npz", {}),
    "actuator_drive.yaml": ("data/accel_demo.npz", {"plugins": (str(REPO / "plugins"),)}),
    "multirate_feedback.yaml": ("data/accel_demo.npz", {}),
    "hatt_texture.yaml": ("data/exploration.npz", {}),
    "surface_render.yaml": ("data/exploration.npz", {}),
    "live_texture.yaml": ("data/exploration.npz", {}),
    "live_audio.yaml": ("data/exploration.npz", {}),
    "pattern_compliance.yaml": ("data/pattern_demo.npz", {}),
    "speed_force_texture.yaml": ("data/speed_force.npz", {}),
}

# scene file (docs/scenes.md) -> recording its planned graph runs on; the golden pins the planned graph's outputs
SCENES: dict[str, str] = {
    "scene_two_surfaces.yaml": "data/scene_strokes.npz",
}


def test_every_example_graph_has_a_golden_test():
    graphs = sorted(p.name for p in GRAPHS.glob("*.yaml"))
    assert graphs, "graphs/ holds no example"
    missing = [g for g in graphs if g not in EXAMPLES and g not in SCENES]
    assert not missing, f"example graphs without a golden test: {missing}; add them to EXAMPLES (graphs) or SCENES (scene files)"


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_example_matches_golden(golden, name):
    recording, options = EXAMPLES[name]
    outputs = golden.check(GRAPHS / name, GRAPHS / recording, GOLDEN / (Path(name).stem + ".npz"), **options)
    for value in outputs.values():
        assert np.all(np.isfinite(value))


@pytest.mark.parametrize("name", sorted(EXAMPLES))
def test_example_validates_from_the_command_line(name, monkeypatch, capsys):
    monkeypatch.chdir(REPO)  # as in the README; actuator_drive.yaml finds plugins/ through its plugins: key
    assert main(["validate", f"graphs/{name}"]) == 0
    assert "ok" in capsys.readouterr().out


@pytest.mark.parametrize("name", sorted(SCENES))
def test_scene_example_plans_and_matches_golden(golden, name, tmp_path, monkeypatch, capsys):
    # planned from the command line as the scene's header says, then validated and run like every example graph
    monkeypatch.chdir(REPO)
    planned = tmp_path / (Path(name).stem + "_planned.yaml")
    assert main(["scene", "plan", f"graphs/{name}", "-o", str(planned)]) == 0
    assert main(["validate", str(planned)]) == 0
    assert "ok" in capsys.readouterr().out
    outputs = golden.check(planned, GRAPHS / SCENES[name], GOLDEN / (Path(name).stem + ".npz"))
    for value in outputs.values():
        assert np.all(np.isfinite(value))


def test_golden_mismatch_is_reported(tmp_path):
    from flowtex.testing import GoldenMismatch, check_golden

    golden_file = tmp_path / "g.npz"
    graph, rec = GRAPHS / "accel_preprocess.yaml", GRAPHS / "data/accel_demo.npz"
    with pytest.raises(GoldenMismatch, match="--update-golden"):
        check_golden(graph, rec, golden_file)
    outputs = check_golden(graph, rec, golden_file, update=True)
    check_golden(graph, rec, golden_file)
    tampered = dict(outputs)
    tampered["envelope"] = outputs["envelope"].copy()
    tampered["envelope"][100] += 1e-12  # a last-bits difference, as another CPU makes (RMS of the envelope ~ 1)
    np.savez(golden_file, **tampered)
    check_golden(graph, rec, golden_file)
    with pytest.raises(GoldenMismatch, match=r"output 'envelope': 1 of 8000 values differ \(must be identical\); first at \(100,\)"):
        check_golden(graph, rec, golden_file, exact=True)
    tampered["envelope"][100] += 1e-3  # a real change
    np.savez(golden_file, **tampered)
    with pytest.raises(GoldenMismatch, match=r"output 'envelope': 1 of 8000 values differ \(allowed \|diff\| 1e-07 x RMS"):
        check_golden(graph, rec, golden_file)
    check_golden(graph, rec, golden_file, atol=2e-3)
