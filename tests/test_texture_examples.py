"""Physical checks on the texture-rendering example graphs (graphs/hatt_texture.yaml, surface_render.yaml, live_texture.yaml).

The golden tests (tests/test_examples.py) pin the numbers; these tests say why
the numbers are right. References are computed here from the recording
itself with numpy/scipy (contact hysteresis, the 125 rad/s Butterworth speed
filter, HaTT's friction rule, the texture force geometry, tap onsets and
incoming speeds), not taken from the nodes under test.
"""

from __future__ import annotations

import importlib.util
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.signal import butter, lfilter
from scipy.spatial.transform import Rotation

import flowtex
from flowtex.cli import main
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set
from flowtex.io.taplib import read_tap_library

REPO = Path(__file__).resolve().parents[1]
GRAPHS = REPO / "graphs"
DATA = GRAPHS / "data"
RATE = 1000.0
MASS_KG = 0.05
ON_N, OFF_N = 0.1, 0.05
MU = json.loads((DATA / "synthetic_texture.json").read_text())["mu"]


def load(name: str, overrides: dict | None = None) -> flowtex.Graph:
    return flowtex.load_graph(GRAPHS / name, overrides)


@pytest.fixture(scope="module")
def rec() -> dict[str, np.ndarray]:
    with np.load(DATA / "exploration.npz") as d:
        return {k: d[k] for k in d.files}


@pytest.fixture(scope="module")
def ref(rec) -> dict[str, np.ndarray]:
    """Independent references computed from the recording."""
    force, pos = rec["normal_force"], rec["position"]
    contact = np.zeros(len(force))
    state = 0.0
    for i, f in enumerate(force):
        state = 1.0 if f >= ON_N else (0.0 if f < OFF_N else state)
        contact[i] = state
    raw = np.zeros_like(pos)
    raw[1:] = np.diff(pos, axis=0) * RATE
    b, a = butter(2, 125.0 / (2 * math.pi), fs=RATE)  # HaTT: 2nd-order low-pass at 125 rad/s
    vel = lfilter(b, a, raw, axis=0)
    vel[:, 2] = 0.0  # tangential part on the plane z = 0
    onsets = np.flatnonzero(np.diff(contact) == 1) + 1
    return {"contact": contact, "velocity": vel, "speed": np.linalg.norm(vel, axis=1), "raw": raw, "onsets": onsets}


@pytest.fixture(scope="module")
def hatt(rec) -> dict[str, np.ndarray]:
    return load("hatt_texture.yaml").run({k: rec[k] for k in ("position", "normal_force", "normal")})


@pytest.fixture(scope="module")
def surface(rec) -> dict[str, np.ndarray]:
    return load("surface_render.yaml").run({k: rec[k] for k in ("position", "normal_force", "normal")})


# --- the bundled data -------------------------------------------------------

def test_bundled_data_is_small_synthetic_and_as_documented(rec):
    assert float(rec["rate"]) == RATE and rec["rate"].ndim == 0
    n = rec["position"].shape[0]
    assert 10 * RATE <= n <= 20 * RATE
    assert rec["position"].shape == (n, 3) and rec["normal"].shape == (n, 3) and rec["normal_force"].shape == (n,)
    assert 0.0 <= rec["normal_force"].min() and 3.5 < rec["normal_force"].max() <= 4.0
    speed = np.linalg.norm(np.diff(rec["position"][:, :2], axis=0), axis=1) * RATE
    assert 240.0 < speed.max() <= 250.0 + 2.0  # 1 um quantisation
    for path in DATA.iterdir():
        assert path.stat().st_size < 400_000, path
    shipped = [p for p in REPO.rglob("*.xml") if ".git" not in p.parts]
    assert not [p for p in shipped if p.name.startswith("Models_")], "the repository must ship no HaTT file"


GENERATOR_RTOL = 1e-9
"""Tolerance of the generator check, relative to the largest |number| in the same JSON list (or to the number
itself) and to the largest |value| of each npz array. The files are deterministic, but numpy's kernels differ
between CPUs in the last bits (measured: the model set's ARMA coefficients and variances move by up to 4.2e-16
relative between an AVX-512 and an AVX2 machine), and rounding of JSON floats shows that at the 16th digit.
1e-9 is over a million times that, and a change of a millionth still fails (tested below)."""


def json_differences(new, old, where: str = "") -> list[str]:
    """Where two decoded JSON documents differ: strings, integers, booleans, keys and lengths exactly, floats within GENERATOR_RTOL."""
    if isinstance(old, dict):
        if not isinstance(new, dict) or sorted(new) != sorted(old):
            return [f"{where or '/'}: keys {sorted(new) if isinstance(new, dict) else type(new).__name__} != {sorted(old)}"]
        return [d for k in old for d in json_differences(new[k], old[k], f"{where}/{k}")]
    if isinstance(old, list):
        if not isinstance(new, list) or len(new) != len(old):
            return [f"{where}: not a list of {len(old)} items"]
        if old and all(type(v) is float for v in old) and all(type(v) is float for v in new):
            a, e = np.asarray(new), np.asarray(old)
            bad = np.abs(a - e) > GENERATOR_RTOL * np.max(np.abs(e))
            return [f"{where}[{i}]: {new[i]!r} != {old[i]!r}" for i in np.flatnonzero(bad)]
        return [d for i, (n, o) in enumerate(zip(new, old, strict=True)) for d in json_differences(n, o, f"{where}[{i}]")]
    if type(old) is float and type(new) is float:
        return [] if abs(new - old) <= GENERATOR_RTOL * abs(old) else [f"{where}: {new!r} != {old!r}"]
    return [] if type(new) is type(old) and new == old else [f"{where}: {new!r} != {old!r}"]


def generator_differences(new_dir: Path, old_dir: Path) -> list[str]:
    """How the files the generator wrote to ``new_dir`` differ from the committed ones in ``old_dir`` (decoded values)."""
    problems = []
    for name in ("synthetic_texture.json", "synthetic_taps.json"):
        new, old = (json.loads((d / name).read_text()) for d in (new_dir, old_dir))
        problems += [f"{name} {d}" for d in json_differences(new, old)]
    for name in ("exploration.npz", "speed_force.npz"):
        with np.load(new_dir / name) as new, np.load(old_dir / name) as old:
            if sorted(new.files) != sorted(old.files):
                problems.append(f"{name}: arrays {sorted(new.files)} != {sorted(old.files)}")
                continue
            for k in old.files:
                a, e = new[k], old[k]
                if a.dtype.kind == "U":
                    if a.shape != e.shape or str(a) != str(e):
                        problems.append(f"{name} {k}")
                elif a.shape != e.shape or not np.all(np.abs(a - e) <= GENERATOR_RTOL * np.max(np.abs(e))):
                    problems.append(f"{name} {k}")
    return problems


@pytest.fixture(scope="module")
def generated(tmp_path_factory) -> Path:
    spec = importlib.util.spec_from_file_location("make_texture_examples", DATA / "make_texture_examples.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    out = tmp_path_factory.mktemp("generated")
    module.main(out)
    return out


def test_generator_reproduces_the_committed_files(generated):
    assert generator_differences(generated, DATA) == []


def test_generator_check_fails_on_a_real_change(generated, tmp_path):
    for name in ("synthetic_texture.json", "synthetic_taps.json", "exploration.npz", "speed_force.npz"):
        (tmp_path / name).write_bytes((generated / name).read_bytes())
    doc = json.loads((tmp_path / "synthetic_texture.json").read_text())
    doc["models"][3]["variance"] *= 1 + 1e-6  # a millionth: far below what anyone would hear, far above rounding
    doc["models"][5]["ar_coeff"][7] += 1e-6 * max(abs(c) for c in doc["models"][5]["ar_coeff"])
    doc["triangles"][0][1] += 1
    (tmp_path / "synthetic_texture.json").write_text(json.dumps(doc))
    with np.load(generated / "exploration.npz") as d:
        arrays = {k: d[k] for k in d.files}
    arrays["normal_force"] = np.roll(arrays["normal_force"], 1)  # one sample late
    np.savez(tmp_path / "exploration.npz", **arrays)
    problems = generator_differences(tmp_path, DATA)
    assert [p.split(":")[0] for p in problems] == ["synthetic_texture.json /triangles[0][1]", "synthetic_texture.json /models[3]/variance",
                                                   "synthetic_texture.json /models[5]/ar_coeff[7]", "exploration.npz normal_force"], problems


def test_recording_has_contact_phases_taps_and_motion_out_of_contact(ref):
    contact, speed = ref["contact"], ref["speed"]
    assert len(ref["onsets"]) == 7
    assert 0.4 < contact.mean() < 0.8
    assert np.sum((contact == 0) & (speed > 100.0)) > 500  # moving through the air: must stay silent
    assert np.sum((contact == 1) & (speed < 1e-9)) > 500   # resting on the surface


# --- hatt_texture.yaml --------------------------------------------------------

def test_contact_matches_force_hysteresis(hatt, ref):
    np.testing.assert_array_equal(hatt["in_contact"], ref["contact"])


def test_texture_is_exactly_silent_out_of_contact(hatt, ref):
    out = ref["contact"] == 0
    assert np.all(hatt["vibration"][out] == 0.0)
    assert np.all(hatt["texture_force"][out] == 0.0)
    sliding = (ref["contact"] == 1) & (ref["speed"] > 10.0)
    assert sliding.sum() > 5000 and np.all(hatt["vibration"][sliding] != 0.0)  # and it plays while sliding


def test_speed_estimate_is_hatts_filter_on_the_recorded_motion(hatt, ref):
    v = hatt["velocity"]
    moving = np.linalg.norm(v, axis=1) > 0
    np.testing.assert_allclose(v[moving], ref["velocity"][moving], rtol=0, atol=1e-8)
    # the stationary gate only ever silences slow motion
    assert np.all(ref["speed"][~moving] < 15.0)


def test_texture_force_geometry(hatt, ref, rec):
    f, vib, v = hatt["texture_force"], hatt["vibration"], hatt["velocity"]
    mag = np.linalg.norm(f, axis=1)
    moving = np.linalg.norm(v, axis=1) > 1e-6
    # magnitude is the effective mass times the vibration, wherever a direction exists
    np.testing.assert_allclose(mag[moving], MASS_KG * np.abs(vib[moving]), rtol=1e-12, atol=0)
    assert np.all(f[~moving] == 0.0)
    # perpendicular to the surface normal and to the independently estimated motion direction
    n = rec["normal"]
    assert np.max(np.abs(np.einsum("ij,ij->i", f, n))) < 1e-15
    d = ref["velocity"][moving] / ref["speed"][moving, None]
    assert np.max(np.abs(np.einsum("ij,ij->i", f[moving], d))) <= 1e-9 * max(mag.max(), 1e-300)
    # sign convention of HaTT: + vibration along (direction of motion x normal)
    expected = MASS_KG * vib[moving, None] * np.cross(d, n[moving])
    np.testing.assert_allclose(f[moving], expected, rtol=0, atol=1e-9 * mag.max())
    assert moving.sum() > 5000


def test_friction_is_hatts_rule_and_opposes_motion(hatt, ref, rec):
    fr, v = hatt["friction_force"], hatt["velocity"]
    fn = np.maximum(rec["normal_force"], 0.0)
    speed = np.linalg.norm(v, axis=1)
    vth = MU / 0.004
    with np.errstate(invalid="ignore", divide="ignore"):
        coulomb = -MU * fn[:, None] * v / speed[:, None]
    expected = np.where((speed < vth)[:, None], -MU * fn[:, None] * 0.004 * v, coulomb)
    np.testing.assert_allclose(fr, expected, rtol=1e-12, atol=1e-15)
    acting = np.linalg.norm(fr, axis=1) > 0
    assert acting.sum() > 5000
    assert np.all(np.einsum("ij,ij->i", fr[acting], ref["velocity"][acting]) < 0)
    assert np.max(np.linalg.norm(np.cross(fr[acting], ref["velocity"][acting]), axis=1)
                  / (np.linalg.norm(fr[acting], axis=1) * ref["speed"][acting])) < 1e-9
    assert np.all(fr[rec["normal_force"] == 0] == 0.0)  # no touch, no friction


def constant_force_strokes(speeds, force=1.5, seconds=1.0):
    """Straight strokes along x at each speed in turn (mm/s), pressing with ``force`` N on the plane z = 0."""
    n = int(seconds * RATE)
    v = np.concatenate([np.full(n, s) for s in speeds])
    pos = np.zeros((len(v), 3))
    pos[:, 0] = np.cumsum(v) / RATE
    return {"position": pos, "normal_force": np.full(len(v), force), "normal": np.tile([0.0, 0.0, 1.0], (len(v), 1))}


def test_vibration_level_grows_with_speed():
    speeds = [0.0, 30.0, 100.0, 200.0, 350.0]
    out = load("hatt_texture.yaml").run(constant_force_strokes(speeds))
    vib = out["vibration"].reshape(len(speeds), -1)[:, 300:]  # skip the 0.3 s settling of each step
    rms = np.sqrt(np.mean(vib ** 2, axis=1))
    assert rms[0] < 0.01 * rms[1]  # at rest (silent corner models)
    assert np.all(rms[2:] > 1.5 * rms[1:-1]), rms  # each step at least 1.5 times louder


def test_tilted_surface_rotates_the_forces(rec, hatt):
    """The same exploration on a tilted plane: forces rotate with it, the vibration is the same signal."""
    rot = Rotation.from_euler("xyz", [25.0, -40.0, 10.0], degrees=True)
    tilted = {"position": rot.apply(rec["position"]), "normal_force": rec["normal_force"], "normal": rot.apply(rec["normal"])}
    out = load("hatt_texture.yaml").run(tilted)
    np.testing.assert_array_equal(out["in_contact"], hatt["in_contact"])
    scale = np.abs(hatt["vibration"]).max()
    np.testing.assert_allclose(out["vibration"], hatt["vibration"], rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(out["texture_force"], rot.apply(hatt["texture_force"]), rtol=0, atol=1e-9 * MASS_KG * scale)
    np.testing.assert_allclose(out["friction_force"], rot.apply(hatt["friction_force"]), rtol=0, atol=1e-9)


def test_a_hatt_xml_file_is_used_with_set(tmp_path, hatt, monkeypatch):
    """docs/texture.md's command line: --set points the graph at a HaTT file (here: the synthetic set written as one)."""
    xml = tmp_path / "HaTT models" / "Models_Synthetic Cork.xml"
    xml.parent.mkdir()
    write_hatt_xml(load_model_set(DATA / "synthetic_texture.json"), xml)
    out = tmp_path / "texture.npz"
    monkeypatch.chdir(REPO)
    assert main(["run", "graphs/hatt_texture.yaml", "--input", "graphs/data/exploration.npz", "--output", str(out),
                 "--set", f"lookup.models={xml}", "--set", f"friction.models={xml}"]) == 0
    with np.load(out) as d:
        for k in hatt:
            np.testing.assert_array_equal(d[k], hatt[k], err_msg=k)


# --- surface_render.yaml ------------------------------------------------------

def test_surface_force_is_texture_plus_friction_plus_tap_along_the_normal(surface, hatt, rec):
    np.testing.assert_array_equal(surface["texture_force"], hatt["texture_force"])
    np.testing.assert_array_equal(surface["vibration"], hatt["vibration"])
    expected = surface["texture_force"] + surface["friction_force"] + surface["tap_force"][:, None] * rec["normal"]
    np.testing.assert_allclose(surface["force"], expected, rtol=0, atol=1e-15)


def test_taps_start_only_at_contact_onsets_with_the_incoming_speed(surface, ref, rec):
    tap = surface["tap_force"]
    lib = read_tap_library(DATA / "synthetic_taps.json")
    expected = np.zeros_like(tap)
    incoming = []
    for k in ref["onsets"]:
        v_in = max(0.0, -ref["raw"][k, 2])  # backward-difference approach speed along -normal at the onset tick
        incoming.append(v_in)
        stop = min(k + lib.length, len(tap))
        expected[k:stop] = MASS_KG * lib.transient(v_in)[:stop - k]
    np.testing.assert_allclose(tap, expected, rtol=1e-12, atol=1e-15)
    # a tap per onset, louder for faster approaches, silent elsewhere
    peaks = [np.abs(tap[k:k + lib.length]).max() for k in ref["onsets"]]
    assert all(p > 0 for p in peaks)
    order = np.argsort(incoming)
    assert np.all(np.diff(np.asarray(peaks)[order]) > 0), (incoming, peaks)
    windows = np.zeros(len(tap), bool)
    for k in ref["onsets"]:
        windows[k:k + lib.length] = True
    assert np.all(tap[~windows] == 0.0)


def test_dahl_friction_is_bounded_passive_and_opposes_sliding(surface, rec, ref):
    fr = surface["friction_force"]
    fn = rec["normal_force"]
    mag = np.linalg.norm(fr, axis=1)
    assert np.all(mag <= MU * fn * (1 + 1e-12) + 1e-15)
    assert np.all(fr[:, 2] == 0.0)  # in the tangent plane
    step = np.zeros_like(rec["position"])
    step[1:] = np.diff(rec["position"], axis=0)
    work = np.einsum("ij,ij->i", fr, step)
    assert work.sum() < 0  # friction takes energy out of the hand, never puts it in
    sliding = (mag >= MU * fn * (1 - 1e-9)) & (fn > 0.2) & (np.linalg.norm(step[:, :2], axis=1) > 0)
    assert sliding.sum() > 3000
    assert np.all(work[sliding] < 0)


# --- live_texture.yaml --------------------------------------------------------

def test_live_graph_has_what_the_map_binds(rec, hatt):
    g = load("live_texture.yaml")
    assert {k: (v.shape, v.unit) for k, v in g.inputs.items()} == {"position": ((3,), "mm"), "normal_force": ((), "N")}
    assert {k: (v.shape, v.unit) for k, v in g.outputs.items()} == {"vibration": ((), "A"), "force": ((3,), "N")}
    out = g.run({"position": rec["position"], "normal_force": rec["normal_force"]})
    np.testing.assert_allclose(out["vibration"], 0.0972 * hatt["vibration"], rtol=1e-15, atol=0)
    np.testing.assert_allclose(out["force"], hatt["texture_force"] + hatt["friction_force"], rtol=0, atol=1e-15)
    # inside the map's clamps, so the guard never has to cut the example's signals
    assert np.abs(out["vibration"]).max() < 1.0
    assert np.all(np.abs(out["force"][:, :2]) <= 4.0) and np.all(out["force"][:, 2] == 0.0)


def test_live_session_on_the_simulated_device_replays_as_the_offline_run(tmp_path, rec, monkeypatch):
    """flowtex live --simulate, recorded; the replay of the session equals the offline run tick for tick.

    The simulated device plays the exploration from 2.6 s on (stroking in
    contact), so the compared numbers are texture and friction, not silence.
    Which live ticks the watchdog forced to safe values depends on the
    machine's load; the replay recomputes the graph from the frames received,
    and those must give exactly the offline numbers.
    """
    from flowtex.runtime.replay import replay_session

    start = int(2.6 * RATE)
    part = {"position": rec["position"][start:start + 600], "normal_force": rec["normal_force"][start:start + 600]}
    np.savez(tmp_path / "strokes.npz", **part, rate=np.float64(RATE))
    monkeypatch.chdir(REPO)
    session = tmp_path / "session.log"
    dbc, cmap = "graphs/devices/example.dbc", "graphs/devices/example_map.yaml"
    assert main(["live", "graphs/live_texture.yaml", "--bus", "virtual", "--dbc", dbc, "--map", cmap,
                 "--simulate", str(tmp_path / "strokes.npz"), "--duration", "0.4", "--quiet", "--record", str(session)]) == 0
    out = tmp_path / "replay.npz"
    report = replay_session(load("live_texture.yaml"), session, dbc, cmap, out)
    assert report.ticks > 100
    offline = load("live_texture.yaml").run(part)
    with np.load(out) as d:
        n = d["vibration"].shape[0]
        assert n == report.ticks
        np.testing.assert_array_equal(d["vibration"], offline["vibration"][:n])
        np.testing.assert_array_equal(d["force"], offline["force"][:n])
    assert np.sum(offline["vibration"][:n] != 0) > 50 and np.sum(np.abs(offline["force"][:n, 0]) > 0.01) > 50


# --- speed and force only (graphs/speed_force_texture.yaml) -----------------

@pytest.fixture(scope="module")
def sf_rec() -> dict[str, np.ndarray]:
    with np.load(DATA / "speed_force.npz") as d:
        return {k: d[k] for k in d.files}


@pytest.fixture(scope="module")
def sf(sf_rec) -> dict[str, np.ndarray]:
    return load("speed_force_texture.yaml").run({"speed": sf_rec["speed"], "normal_force": sf_rec["normal_force"]})


def _since(mask: np.ndarray) -> np.ndarray:
    """Samples since ``mask`` was last False (0 where it is False)."""
    out = np.zeros(mask.shape[0])
    for i in range(1, mask.shape[0]):
        out[i] = out[i - 1] + 1 if mask[i] else 0
    return out


def test_speed_force_graph_needs_only_speed_and_force(sf_rec, rec):
    g = load("speed_force_texture.yaml")
    assert {k: (v.shape, v.unit) for k, v in g.inputs.items()} == {"speed": ((), "mm/s"), "normal_force": ((), "N")}
    assert {k: (v.shape, v.unit) for k, v in g.outputs.items()} == {"vibration": ((), "m/s^2"), "texture_force": ((), "N"),
                                                                    "friction_force": ((), "N")}
    # the bundled input is the exploration without position: same force, speed of the same path
    np.testing.assert_array_equal(sf_rec["normal_force"], rec["normal_force"])
    path_speed = np.linalg.norm(np.diff(rec["position"][:, :2], axis=0), axis=1) * RATE
    # 1 um position steps make the difference's speed scatter by ~1 mm/s; the keyframes have no such noise
    assert np.median(np.abs(path_speed - sf_rec["speed"][1:])) < 1.0


def test_speed_force_texture_is_the_vibration_times_the_mass_and_silent_at_rest(sf, sf_rec):
    v, fn, speed = sf["vibration"], sf_rec["normal_force"], sf_rec["speed"]
    np.testing.assert_array_equal(sf["texture_force"], MASS_KG * v)
    moving = (fn > 0.2) & (speed > 50.0)
    rms = float(np.sqrt(np.mean(v[moving] ** 2)))
    assert moving.sum() > 3000 and rms > 0.1
    # exactly 0 out of contact (released below 0.05 N), from the first tick: the graph mutes by the contact state, as
    # hatt_texture.yaml does (before, the synthesis filter rang on for ~50 ms after the tool left the surface, and a
    # HaTT set kept its residual there for ever); at rest in contact, silent once the filter has rung down (50 ms):
    # HaTT's low-speed substitute leaves at most ~3e-4 of a set's largest variance, sqrt(3e-4) = 0.017 of its amplitude
    released = fn < 0.05
    assert released.sum() > 500 and np.all(v[released] == 0.0)
    settled = _since((speed == 0.0) & (fn > 0.0)) > 50
    assert settled.sum() > 500
    assert np.max(np.abs(v[settled])) < 0.02 * rms


def test_speed_force_texture_is_silent_out_of_contact_under_hatts_rule(sf_rec):
    """With HaTT's own rule (outside: fade), a set keeps a faint residual at force 0 (docs/texture.md); the example
    graph is silent there all the same, as every surface at rest and out of contact must be (DESIGN.md)."""
    g = load("speed_force_texture.yaml", overrides={"lookup.outside": "fade"})
    out = g.run({"speed": sf_rec["speed"], "normal_force": sf_rec["normal_force"]})
    released = sf_rec["normal_force"] < 0.05
    assert np.all(out["vibration"][released] == 0.0) and np.any(out["vibration"][~released] != 0.0)


def test_speed_force_friction_is_hatts_rule_on_the_speed(sf, sf_rec):
    fn, speed = np.maximum(sf_rec["normal_force"], 0.0), sf_rec["speed"]
    expected = np.where(speed < MU / 0.004, MU * fn * 0.004 * speed, MU * fn)
    np.testing.assert_allclose(sf["friction_force"], expected, rtol=1e-12, atol=1e-15)
    assert np.sum(expected > 0.1) > 3000
