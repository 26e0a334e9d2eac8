"""Scene planning: salience figures, decisions on the study surfaces of Culbertson & Kuchenbecker 2017, JSON, forcing, thresholds, file errors."""

from __future__ import annotations

import json

import numpy as np
import pytest
import scipy.signal

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.datasets.study import STUDY_SURFACES, study_tap_library, write_study_scene
from flowtex.errors import GraphError
from flowtex.models.taps import spectral_centroid
from flowtex.scene.file import parse_scene
from flowtex.scene.plan import plan_scene
from flowtex.scene.salience import texture_power_grid, trajectory_ranges

CHECKED = ("EPDM_Foam", "Whiteboard", "MDF", "Silk_1", "Brick_1", "Nylon_Mesh", "Sandpaper_100", "ABS_Plastic", "Carpet_3")


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    folder = tmp_path_factory.mktemp("study")
    scene = write_study_scene(folder, CHECKED)
    out = folder / "graph.yaml"
    plan_json = folder / "plan.json"
    assert main(["scene", "plan", str(scene), "-o", str(out), "--json", str(plan_json), "--explain"]) == 0
    return folder, scene, json.loads(plan_json.read_text())


def test_texture_power_at_model_points_matches_impulse_energy():
    # At a model's own (speed, force) the lookup returns that model; its power is var * g^2 * sum h^2,
    # with h from scipy's lfilter of the stored coefficients (independent of the Lyapunov solution and of the LSF path).
    ms = synthetic_model_set([50.0, 150.0, 250.0], [0.5, 1.5, 2.5], 6, 4)
    grid = texture_power_grid(ms, np.array([150.0, 250.0]), np.array([1.5, 0.5]))
    for i, s in enumerate((150.0, 250.0)):
        for j, f in enumerate((1.5, 0.5)):
            m = int(np.flatnonzero((ms.speeds == s) & (ms.forces == f))[0])
            impulse = np.zeros(4000)
            impulse[0] = 1.0
            h = scipy.signal.lfilter(ms.ma_coeff[m], ms.ar_coeff[m], impulse)
            expected = ms.variance[m] * ms.gain[m] ** 2 * np.sum(h * h)
            # 1e-9: LSF -> polynomial round trip and the 4000-sample truncation (poles <= 0.96: h^2 < 1e-100 there)
            assert grid[i, j] == pytest.approx(expected, rel=1e-9)


def test_trajectory_ranges_of_a_known_stroke():
    t = np.arange(2000) / 1000.0
    speed = 50.0 + 100.0 * t  # mm/s, x only
    pos = np.column_stack([np.cumsum(speed) / 1000.0, np.zeros_like(t), 5.0 * t])  # z motion is along the normal
    force = np.where(t < 1.0, 0.0, 1.0 + t)
    normal = np.tile([0.0, 0.0, 2.0], (2000, 1))
    (s_lo, s_hi), (f_lo, f_hi) = trajectory_ranges(pos, force, 1000.0, normal)
    # in contact for t in [1, 2): tangential speed 150..250, force 2..3; 5th/95th percentiles of a linear ramp
    assert s_lo == pytest.approx(155.0, abs=0.2) and s_hi == pytest.approx(245.0, abs=0.2)
    assert f_lo == pytest.approx(2.05, abs=2e-3) and f_hi == pytest.approx(2.95, abs=2e-3)


def test_study_plan_keeps_what_002_says(study):
    _, _, plan = study
    assert set(plan) == set(CHECKED)
    for comps in plan.values():
        for record in comps.values():
            assert set(record) == {"keep", "salience", "threshold", "reason"}
    assert plan["EPDM_Foam"]["friction"]["keep"] is True
    for key in ("Whiteboard", "MDF"):
        assert plan[key]["friction"]["keep"] is False
    for key in ("Whiteboard", "Silk_1"):
        assert plan[key]["texture"]["keep"] is False
    for key in ("Brick_1", "Nylon_Mesh", "Sandpaper_100", "ABS_Plastic", "Carpet_3", "MDF"):
        assert plan[key]["texture"]["keep"] is True
    assert plan["Carpet_3"]["taps"]["keep"] is False
    assert plan["Whiteboard"]["taps"]["keep"] is True
    # the salience figures are the targets the sets were built for (texture) and the data given (mu, centroid)
    targets = {s.key: s for s in STUDY_SURFACES}
    for key in CHECKED:
        assert plan[key]["texture"]["salience"] == pytest.approx(targets[key].power, rel=1e-9)
        assert plan[key]["friction"]["salience"] == targets[key].mu
        assert plan[key]["taps"]["salience"] == pytest.approx(targets[key].centroid_hz, abs=1e-4)


def test_tap_centroid_of_study_library_is_independent_dft():
    # spectral centroid by an explicit DFT sum (not numpy.fft) for Carpet 3 at 50..100 mm/s
    lib = study_tap_library(next(s for s in STUDY_SURFACES if s.key == "Carpet_3"))
    n = lib.length
    f = np.arange(n // 2 + 1) * lib.sample_rate_hz / n
    sc = []
    for v in (50.0, 60.0, 70.0, 80.0, 90.0, 100.0):
        x = lib.transient(v)
        X = np.array([np.sum(x * np.exp(-2j * np.pi * k * np.arange(n) / n)) for k in range(n // 2 + 1)])
        p = np.abs(X) ** 2
        sc.append(np.sum(p * f) / np.sum(p))
    assert spectral_centroid(lib) == pytest.approx(np.mean(sc), rel=1e-9)
    assert np.mean(sc) == pytest.approx(47.8, abs=1e-4)


def test_planned_graph_holds_only_kept_components(study):
    folder, _, plan = study
    text = (folder / "graph.yaml").read_text()
    assert "EPDM_Foam_friction" in text and "Whiteboard_friction" not in text and "MDF_friction" not in text
    assert "Whiteboard_lookup" not in text and "Brick_1_lookup" in text
    assert "Carpet_3_taps" not in text and "Whiteboard_taps" in text
    assert main(["validate", str(folder / "graph.yaml")]) == 0


def _scene(tmp_path, body: str, name: str = "s.yaml"):
    path = tmp_path / name
    path.write_text(body)
    return path


def test_forcing_and_threshold_overrides(study, tmp_path):
    folder, _, _ = study
    body = (f"flowtex: 1\nname: forced\ntrajectory: {{speed: [50, 250], force: [0.5, 2.5]}}\n"
            f"thresholds: {{friction: 0.1}}\n"
            f"surfaces:\n"
            f"  wb: {{models: {folder}/Whiteboard.json, taps: {folder}/Whiteboard_taps.json, keep: [texture], drop: [taps]}}\n"
            f"  carpet: {{models: {folder}/Carpet_3.json, mu: 0.05}}\n")
    plan = plan_scene(parse_scene(body, tmp_path / "forced.yaml"))
    wb = plan["wb"].decisions
    assert wb["texture"].keep and "forced by keep" in wb["texture"].reason
    assert not wb["taps"].keep and "forced by drop" in wb["taps"].reason
    assert wb["friction"].keep and wb["friction"].threshold == 0.1  # 0.17 >= overridden 0.1
    carpet = plan["carpet"].decisions
    assert carpet["friction"].salience == 0.05 and not carpet["friction"].keep  # mu from the scene beats the set's
    assert "taps" not in carpet  # no library: no taps component


def test_pattern_without_node_type_is_dropped(study, tmp_path):
    folder, _, _ = study
    body = (f"flowtex: 1\ntrajectory: {{speed: [50, 250], force: [0.5, 2.5]}}\n"
            f"surfaces:\n  a: {{models: {folder}/MDF.json, pattern: {{period: 2.0}}}}\n")
    plan = plan_scene(parse_scene(body, tmp_path / "p.yaml"), frozenset({"texture_lookup"}))
    assert plan["a"].decisions["pattern"].keep is False
    plan = plan_scene(parse_scene(body, tmp_path / "p.yaml"), frozenset({"patterned_texture"}))
    assert plan["a"].decisions["pattern"].keep is True


@pytest.mark.parametrize("body, where, words", [
    ("flowtex: 1\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: m.json, tapps: 1}\n", ":4:23:", "taps"),
    ("flowtex: 1\ntrajectory: {speed: [250, 50], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: m.json}\n", ":2:21:", "low 250"),
    ("flowtex: 1\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: m.json, drop: [texure]}\n", ":4:30:", "texture"),
    ("flowtex: 1\ntrajectory: {speed: [50, 250]}\nsurfaces:\n  a: {models: m.json}\n", ":2:13:", "missing force"),
    ("flowtex: 1\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  2a: {models: m.json}\n", ":4:3:", "not valid"),
    ("flowtex: 2\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: m.json}\n", ":1:10:", "version"),
    ("flowtex: 1\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nselect: {fixed: b}\nsurfaces:\n  a: {models: m.json}\n", ":3:17:", "no surface"),
])
def test_scene_file_errors_point_at_line_and_column(tmp_path, body, where, words):
    with pytest.raises(GraphError) as exc:
        parse_scene(body, tmp_path / "bad.yaml")
    assert where in str(exc.value) and words in str(exc.value)


def test_missing_model_file_is_reported_at_its_line(tmp_path, capsys):
    scene = _scene(tmp_path, "flowtex: 1\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\nsurfaces:\n  a: {models: nothere.json}\n")
    out = tmp_path / "g.yaml"
    assert main(["scene", "plan", str(scene), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert "s.yaml:4:15:" in err and "nothere.json" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_scene_live_without_a_device_says_how_to_add_one(study, capsys):
    _, scene, _ = study
    assert main(["scene", "live", str(scene), "--duration", "0.1"]) == 1
    assert "device: {dbc: FILE, map: FILE}" in capsys.readouterr().err


def test_scene_run_unknown_surface(study, tmp_path, capsys):
    _, scene, _ = study
    assert main(["scene", "run", str(scene), "--input", str(tmp_path / "none.npz"), "--surface", "Whitebord"]) == 1
    assert "Whiteboard" in capsys.readouterr().err  # the suggestion


def test_reasons_state_the_figure_and_its_threshold_in_one_unit(study):
    """'tap spectral centroid 47.8 Hz < threshold 60' left the threshold's unit out, and 'friction coefficient 1.39
    mu_k' wrote the symbol where a unit goes (the --json plan and --explain carry the same reasons)."""
    _, _, plan = study
    seen = set()
    for decisions in plan.values():
        for component, d in decisions.items():
            if "forced" in d["reason"] or component not in ("texture", "friction", "taps"):
                continue
            unit = {"texture": " (m/s^2)^2", "friction": "", "taps": " Hz"}[component]
            figure = {"texture": "mean vibration power", "friction": "friction coefficient mu_k",
                      "taps": "tap spectral centroid"}[component]
            sign = ">=" if d["keep"] else "<"
            assert d["reason"] == (f"{'kept' if d['keep'] else 'dropped'}: {figure} {d['salience']:.3g}{unit} {sign} "
                                   f"threshold {d['threshold']:g}{unit}")
            seen.add(component)
    assert seen == {"texture", "friction", "taps"}
