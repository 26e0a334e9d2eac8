"""Scene keys ``stiffness`` and ``compliance``: the base-surface spring F = stiffness x k_c x penetration along the normal.

Planner decisions (figure, reason, forcing, a compliance without a stiffness,
an invalid estimate) and one offline run of a three-surface scene whose other
components all drop, so the spring is the whole force: checked against
k x max(penetration, 0) computed here from the recording.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.errors import GraphError
from flowtex.fit.compliance import FORMAT_NAME
from flowtex.scene.file import parse_scene
from flowtex.scene.plan import plan_scene
from tests.conftest import REPO

MODELS = REPO / "graphs" / "data" / "synthetic_texture.json"  # texture 0.20 (m/s^2)^2 and mu 0.3: both dropped by default
HEAD = "flowtex: 1\nname: springs\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\n"


def _estimate(path, k_c, valid=True, reason="ok"):
    # the document 'flowtex fit compliance' writes (docs/compliance.md)
    path.write_text(json.dumps({"format": FORMAT_NAME, "version": 1, "k_c": k_c, "sigma": 0.1, "valid": valid, "reason": reason}))
    return path


def test_decisions_and_reasons(tmp_path):
    _estimate(tmp_path / "foam.json", 0.3, valid=False, reason="poor fit (weighted R^2 below r2_min)")
    body = HEAD + (f"surfaces:\n"
                   f"  a: {{models: {MODELS}, stiffness: 0.5, compliance: 0.4}}\n"
                   f"  b: {{models: {MODELS}, compliance: 0.4}}\n"
                   f"  c: {{models: {MODELS}, stiffness: 0.25, compliance: foam.json}}\n"
                   f"  d: {{models: {MODELS}, stiffness: 0.25, drop: [stiffness]}}\n"
                   f"  e: {{models: {MODELS}, stiffness: 0.8, compliance: 0}}\n")
    plan = plan_scene(parse_scene(body, tmp_path / "s.yaml"))
    a = plan["a"].decisions["stiffness"]
    assert a.keep and a.salience == pytest.approx(0.2, rel=1e-15) and plan["a"].stiffness == a.salience  # 0.5 N/mm x k_c 0.4
    assert "compliance k_c 0.4" in a.reason and "penetration" in a.reason
    b = plan["b"].decisions["stiffness"]  # nothing to scale: said so, not silently ignored
    assert not b.keep and "no stiffness" in b.reason and plan["b"].stiffness is None
    c = plan["c"].decisions["stiffness"]  # an estimate that is not valid leaves the stiffness unscaled, and says why
    assert c.keep and c.salience == 0.25 and "not valid (poor fit" in c.reason
    d = plan["d"].decisions["stiffness"]
    assert not d.keep and "forced by drop" in d.reason and plan["d"].stiffness is None
    e = plan["e"].decisions["stiffness"]  # k_c 0: the spring would push nothing
    assert not e.keep and e.salience == 0.0
    assert "stiffness" not in plan_scene(parse_scene(HEAD + f"surfaces:\n  f: {{models: {MODELS}}}\n", tmp_path / "s.yaml"))["f"].decisions


@pytest.mark.parametrize("surface, where, words", [
    ("{models: m.json, compliance: 1.5}", ":5:35:", "between 0 (soft) and 1 (stiff)"),
    ("{models: m.json, stiffness: -1}", ":5:34:", "stiffness (N/mm)"),
    ("{models: m.json, keep: [stifness]}", ":5:30:", "did you mean 'stiffness'"),
])
def test_file_errors(tmp_path, surface, where, words):
    with pytest.raises(GraphError) as exc:
        parse_scene(HEAD + f"surfaces:\n  a: {surface}\n", tmp_path / "bad.yaml")
    assert where in str(exc.value) and words in str(exc.value)


def test_keep_without_stiffness_and_unreadable_estimate_are_errors(tmp_path):
    with pytest.raises(GraphError, match="keep: stiffness, but the surface gives no stiffness"):
        plan_scene(parse_scene(HEAD + f"surfaces:\n  a: {{models: {MODELS}, keep: [stiffness]}}\n", tmp_path / "s.yaml"))
    (tmp_path / "bad.json").write_text('{"format": "flowtex-texture-models", "version": 1}')
    with pytest.raises(GraphError, match=r"s.yaml:5:\d+: surface 'a': .*bad.json.*flowtex-compliance"):
        plan_scene(parse_scene(HEAD + f"surfaces:\n  a: {{models: {MODELS}, stiffness: 1, compliance: bad.json}}\n", tmp_path / "s.yaml"))


@pytest.fixture(scope="module")
def springs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("springs")
    _estimate(folder / "cork.json", 0.4)
    scene = folder / "springs.yaml"
    scene.write_text(HEAD + f"surfaces:\n"
                            f"  soft: {{models: {MODELS}, stiffness: 0.5, compliance: 0.5}}\n"
                            f"  hard: {{models: {MODELS}, stiffness: 1.0}}\n"
                            f"  cork: {{models: {MODELS}, stiffness: 2.0, compliance: cork.json}}\n")
    with np.load(REPO / "graphs" / "data" / "scene_strokes.npz") as d:
        rec = {k: d[k][2000:8000] for k in ("position", "normal_force", "normal", "penetration")}
    surface = np.zeros(6000)
    surface[3000:4500] = 1.0  # soft -> hard at 5.0 s, -> cork at 6.5 s: both mid-stroke
    surface[4500:] = 2.0
    np.savez(folder / "rec.npz", surface=surface, **rec)
    assert main(["scene", "plan", str(scene), "-o", str(folder / "g.yaml"), "--json", str(folder / "plan.json")]) == 0
    assert main(["scene", "run", str(scene), "--input", str(folder / "rec.npz"), "-o", str(folder / "out.npz")]) == 0
    with np.load(folder / "out.npz") as d:
        out = {k: d[k] for k in d.files}
    return out, rec, surface, json.loads((folder / "plan.json").read_text())


def test_plan_json_names_the_component(springs):
    _, _, _, plan = springs
    assert {k: plan[k]["stiffness"]["salience"] for k in plan} == pytest.approx({"soft": 0.25, "hard": 1.0, "cork": 0.8}, rel=1e-15)
    assert all(plan[k]["stiffness"]["keep"] for k in plan)
    assert all(not plan[k]["texture"]["keep"] and not plan[k]["friction"]["keep"] for k in plan)


def test_spring_force_is_stiffness_times_penetration_along_the_normal(springs):
    out, rec, surface, _ = springs
    assert set(out) >= {"force", "spring_force", "in_contact"} and "vibration" not in out
    k = np.array([0.25, 1.0, 0.8])[surface.astype(int)]  # N/mm, the rendered stiffness of the active surface
    depth = np.maximum(rec["penetration"], 0.0)  # mm
    expected = k * depth
    fade = 10  # ticks: select.fade 0.01 s at 1 kHz
    steady = np.ones(6000, bool)
    for s in (3000, 4500):
        steady[s:s + fade] = False
    # one multiplication per tick, as here: equal to rounding
    np.testing.assert_allclose(out["spring_force"][steady], expected[steady], rtol=1e-15, atol=0)
    # along the unit normal (+z here): the spring is the whole force, since every other component dropped
    np.testing.assert_allclose(out["force"][:, 2], out["spring_force"], rtol=1e-15, atol=0)
    assert np.all(out["force"][:, :2] == 0.0)
    assert expected[steady].max() > 1.0 and np.sum(depth[:3000] > 0) > 1000  # really pressing in
    # the crossfade between two springs stays between them: no burst at a switch
    for s, (k0, k1) in ((3000, (0.25, 1.0)), (4500, (1.0, 0.8))):
        w = slice(s, s + fade)
        lo, hi = np.minimum(k0, k1) * depth[w], np.maximum(k0, k1) * depth[w]
        assert np.all(out["spring_force"][w] >= lo - 1e-12) and np.all(out["spring_force"][w] <= hi + 1e-12)
