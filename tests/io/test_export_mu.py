"""Issue 18 (3): a model set without friction exports no mu, renders with a clean error, and `fit friction --into` round-trips."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import friction_session
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.hatt import read_hatt_xml, write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from tests.conftest import REPO


def _no_friction_set():
    return synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2, mu=None)


def _write(ms, path):
    return write_hatt_xml(ms, path, texture=7) if path.suffix == ".xml" else save_model_set(ms, path)


def test_no_friction_writes_no_mu_and_reads_back_none(tmp_path):
    ms = _no_friction_set()
    xml = write_hatt_xml(ms, tmp_path / "s.xml")
    assert "<mu>" not in xml.read_text()
    assert read_hatt_xml(xml).mu is None
    assert json.loads(save_model_set(ms, tmp_path / "s.json").read_text())["mu"] is None
    # an empty <mu/> (another writer's way of saying "none") reads as absent too, never as 0
    text = xml.read_text().replace("<numMod>", "<mu></mu>\n  <numMod>", 1)
    (tmp_path / "empty.xml").write_text(text)
    assert read_hatt_xml(tmp_path / "empty.xml").mu is None


def test_rendering_a_set_without_friction_is_refused_in_one_line(tmp_path, capsys):
    """The README's HaTT command on the XML export gives the JSON's clean error (was: internal error: ZeroDivisionError)."""
    messages = {}
    for suffix in (".xml", ".json"):
        surface = _write(_no_friction_set(), tmp_path / f"surface{suffix}")
        code = main(["run", str(REPO / "graphs" / "hatt_texture.yaml"), "--input", str(REPO / "graphs" / "data" / "exploration.npz"),
                     "--output", str(tmp_path / "out.npz"), "--set", f"lookup.models={surface}", "--set", f"friction.models={surface}"])
        err = capsys.readouterr().err.strip()
        assert code == 1 and len(err.splitlines()) == 1, err
        assert "internal error" not in err and "no usable friction coefficient" in err, err
        messages[suffix] = err.replace(str(surface), "SURFACE")
    assert messages[".xml"] == messages[".json"]


@pytest.mark.parametrize("suffix", [".xml", ".json"])
def test_fit_friction_into_round_trips(tmp_path, capsys, suffix):
    """`fit friction --into` stores mu in the file's own format; everything else reads back unchanged."""
    rec = friction_session(mu=0.35, duration_s=6.0, seed=2)
    path = rec.save(tmp_path / "fr.npz")
    ms = _no_friction_set()
    surface = _write(ms, tmp_path / f"surface{suffix}")
    out = tmp_path / "mu.json"
    assert main(["fit", "friction", str(path), "--force", "normal_force", "--friction-force", "tangential_force",
                 "-o", str(out), "--into", str(surface)]) == 0
    capsys.readouterr()
    mu = json.loads(out.read_text())["mu"]
    back = load_model_set(surface)
    assert back.mu == mu  # written with repr: exact
    assert mu == pytest.approx(0.35, rel=0.03)  # friction_session's tolerance (tests/fit/test_fit_friction_taps.py)
    for key in ("speeds", "forces", "ar_lsf", "ma_lsf", "variance", "gain", "triangles"):
        assert np.array_equal(getattr(back, key), getattr(ms, key)), key
    if suffix == ".xml":
        assert back.metadata["texture"] == "7" and surface.read_text().count("<mu>") == 1
