"""Joins between verbs that a user hits when chaining them (issues 17 and 18, found by running the CLI end to end)."""

from __future__ import annotations

import json
import os
import stat
import threading
from pathlib import Path

import pytest

from flowtex.errors import DataError, GraphError
from flowtex.graph.spec import parse_spec
from flowtex.io.atomic import check_output, write_json_atomic
from flowtex.io.recordings import load_recording

GRAPH = """flowtex: 1
name: g
rate: 1000
inputs:
  x: {}
nodes:
  k: {type: gain, params: {k: 2.0}}
edges:
  - x -> k.x
outputs: {y: k.y}
"""


def test_set_rate_sets_the_graph_rate(tmp_path: Path) -> None:
    # `--set rate=2000` is how a resampled model set is rendered (docs/fitting.md); it used to be refused.
    spec = parse_spec(GRAPH, tmp_path / "g.yaml", {"rate": 2000})
    assert spec.rate == 2000.0


@pytest.mark.parametrize("bad", [0, -5, float("nan"), "fast", True, 1e12, 1_000_001])
def test_set_rate_refuses_a_rate_that_is_not_positive(tmp_path: Path, bad: object) -> None:
    with pytest.raises(GraphError, match=r"rate must be a number of Hz in \(0, 1e\+06\]"):
        parse_spec(GRAPH, tmp_path / "g.yaml", {"rate": bad})


def test_a_graph_file_rate_beyond_1_mhz_is_refused_at_its_line(tmp_path: Path) -> None:
    # a rate of 1e12 Hz used to pass validation and then suggest 'models resample --rate 1e+12', which refuses it
    path = tmp_path / "g.yaml"
    path.write_text(GRAPH.replace("rate: 1000", "rate: 1000000000000"))
    with pytest.raises(GraphError, match=r"g\.yaml:\d+:\d+: rate must be a number of Hz in \(0, 1e\+06\], got 1000000000000"):
        parse_spec(path.read_text(), path, {})


def test_output_into_a_fifo_writes_into_it_and_keeps_it(tmp_path: Path) -> None:
    # `-o /dev/null` used to rename a temporary file over the device, turning /dev/null into a regular file (as root).
    # A FIFO is the same kind of target (exists, not a regular file) without touching the machine's /dev.
    fifo = tmp_path / "pipe.json"
    os.mkfifo(fifo)
    got: list[bytes] = []
    reader = threading.Thread(target=lambda: got.append(fifo.read_bytes()))
    reader.start()
    assert check_output(fifo) == fifo
    write_json_atomic(fifo, {"mu": 0.5})
    reader.join(timeout=10)
    assert stat.S_ISFIFO(os.stat(fifo).st_mode)
    assert json.loads(got[0]) == {"mu": 0.5}
    assert [p.name for p in tmp_path.iterdir()] == ["pipe.json"]   # no temporary file left behind


@pytest.mark.parametrize("content", [
    b"",                                     # numpy: EOFError -> "internal error"
    b"garbage\n",                            # numpy: "pickled data ... allow_pickle" advice
    b"\x93NUMPY\x01\x00" + b" " * 60,        # an .npy saved under an .npz name
])
def test_a_file_that_is_not_an_npz_is_refused_in_one_line(tmp_path: Path, content: bytes) -> None:
    path = tmp_path / "rec.npz"
    path.write_bytes(content)
    with pytest.raises(DataError, match=r"rec\.npz: .*npz") as info:
        load_recording(path)
    assert "pickle" not in str(info.value) and "\n" not in str(info.value)


def test_compare_of_a_resampled_set_measures_shape_below_the_old_nyquist() -> None:
    # `models resample` 1 -> 2 kHz, `resample` of the recording, then `compare`: the recording holds only the
    # resampler's transition band above 0.8 x 500 Hz, so an LSD to 1 kHz said 2.5 dB for a twin that agrees within 0.6.
    import numpy as np
    from scipy.signal import butter, sosfiltfilt

    from flowtex.datasets.model_sets import synthetic_model_set
    from flowtex.fit.compare import CompareOptions, compare_signals
    from flowtex.fit.resampled_band import resampled_band_hz

    rate = 2000.0
    rng = np.random.default_rng(0)
    render = rng.standard_normal(40000)
    recorded = sosfiltfilt(butter(8, 450.0, fs=rate, output="sos"), render)   # content of a 1 kHz recording, upsampled
    full = compare_signals(recorded, [render], rate)
    band = compare_signals(recorded, [render], rate, CompareOptions(max_freq_hz=400.0))
    assert full.lsd_db > 3.0                       # the 450-1000 Hz bins within 40 dB of the peak dominate
    assert band.lsd_db < 0.5                        # identical below 400 Hz (8th-order Butterworth: < 0.1 dB there)
    assert band.max_freq_hz == 400.0 and band.to_json()["max_freq_hz"] == 400.0

    ms = synthetic_model_set(np.array([50.0, 100.0]), np.array([1.0, 2.0]), 4, 2, grid=True, sample_rate=2000.0)
    assert resampled_band_hz(ms) == float("inf")
    ms.metadata["resample"] = {"from_hz": 1000.0, "to_hz": 2000.0}
    assert resampled_band_hz(ms) == 400.0           # flowtex.dsp.resample.PASSBAND x the old Nyquist
    # resampled down (1 kHz -> 500 Hz): the models keep their spectrum up to 0.9 x the new Nyquist only, and a
    # recording resampled alike holds its passband up to 0.8 x it; graded to 250 Hz, one fitted surface's 500 Hz twin
    # scored LSD 3.09 dB where it scores 1.10 dB up to 200 Hz (docs/fitting.md)
    ms.sample_rate = 500.0
    ms.metadata["resample"] = {"from_hz": 1000.0, "to_hz": 500.0}
    assert resampled_band_hz(ms) == 200.0           # PASSBAND x the lower (new) Nyquist


def test_friction_warning_quotes_one_force_ratio_for_either_fit() -> None:
    # A tangential force that ignores the normal force: both fits warn and quote "force ratio"; it was weighted by each
    # fit's own IRLS weights, so the same recording read 0.455 through the origin and 0.439 with --offset yes.
    import re

    import numpy as np

    from flowtex.fit.friction import fit_friction

    rng = np.random.default_rng(1)
    normal = 0.5 + 3.0 * rng.random(5000)
    tangential = 0.6 + 0.05 * rng.standard_normal(5000)
    ratios = set()
    for offset in (False, True):
        fit = fit_friction(normal, tangential, offset=offset)
        ratios.add(re.search(r"force ratio ([0-9.]+)", fit.warning).group(1))
    expected = f"{tangential.sum() / normal.sum():.3f}"   # mean T / mean N, all samples in contact
    assert ratios == {expected}


def test_a_signed_velocity_given_as_speed_is_named(tmp_path: Path) -> None:
    # `fit texture --speed v` with a signed velocity said "no stationary piece ... none is moving" at 240 mm/s.
    import numpy as np

    from flowtex.fit.inputs import check_speed_magnitude

    t = np.arange(5000) / 1000.0
    with pytest.raises(DataError, match=r"speed is negative in 50 % .*--speed takes the speed magnitude"):
        check_speed_magnitude(200.0 * np.sin(2 * np.pi * t), "rec.npz: signal 'v' (--speed)")
    speed = np.abs(200.0 * np.sin(2 * np.pi * t))
    speed[::50] -= 0.5                              # a resampled magnitude dipping below 0 near rest is accepted
    check_speed_magnitude(speed, "rec.npz: signal 'speed' (--speed)")


def test_holdout_one_is_refused_by_the_option_that_said_it_was_valid() -> None:
    # `--holdout 1` passed the option check ("valid (0, 1]") and was then refused by the library ("between 0 and 1").
    import argparse

    from flowtex.cli.options import number_in_range

    with pytest.raises(argparse.ArgumentTypeError, match=r"valid \(0, 1\)"):
        number_in_range("1", 0.0, 1.0, low_open=True, high_open=True)
    assert number_in_range("0.999", 0.0, 1.0, low_open=True, high_open=True) == 0.999
    assert number_in_range("1", 0.0, 1.0) == 1.0    # closed by default, as before


def test_models_resample_writes_the_format_its_output_suffix_names(tmp_path: Path, flowtex_cli) -> None:
    # `models resample IN.xml -o OUT.xml` wrote JSON into OUT.xml (HaTT's tools cannot read it); `-o OUT.txt` too.
    import subprocess
    import sys

    import numpy as np

    from flowtex.datasets.model_sets import synthetic_model_set
    from flowtex.io.modelset import load_model_set, save_model_set

    src = save_model_set(synthetic_model_set(np.array([50.0, 150.0]), np.array([1.0, 3.0]), 4, 2, grid=True), tmp_path / "in.json")
    outs = {}
    for suffix in (".json", ".xml"):  # in this process: the files written are the point
        outs[suffix] = tmp_path / f"out{suffix}"
        done = flowtex_cli("models", "resample", src, "--rate", "2000", "-o", outs[suffix])
        assert done.returncode == 0, done.stderr
    assert outs[".xml"].read_text().startswith("<?xml")
    xml, native = load_model_set(outs[".xml"]), load_model_set(outs[".json"])
    assert xml.metadata["format"] == "hatt-xml" and xml.sample_rate == native.sample_rate == 2000.0
    np.testing.assert_array_equal(xml.variance, native.variance)       # repr floats: an exact round trip
    np.testing.assert_array_equal(xml.ar_lsf, native.ar_lsf)
    # a process of its own: the interpreter's exit code, and no traceback on its stderr
    done = subprocess.run([sys.executable, "-m", "flowtex", "models", "resample", str(src), "--rate", "2000",
                           "-o", str(tmp_path / "out.txt")], capture_output=True, text=True, timeout=300)
    assert done.returncode != 0 and ".json" in done.stderr and "Traceback" not in done.stderr
    assert not (tmp_path / "out.txt").exists()


@pytest.mark.parametrize(("flags", "message"), [
    (["-o", "surf.xml"], "-o writes flowtex's JSON model set"),       # wrote JSON into surf.xml
    (["-o", "surf.json", "--xml", "hatt.json"], "--xml writes HaTT's XML"),
])
def test_fit_texture_refuses_an_output_whose_suffix_names_the_other_format(tmp_path: Path, capsys, flags, message) -> None:
    import numpy as np

    from flowtex.cli.main import main
    from flowtex.io.recordings import save_recording

    n = 4000
    rec = save_recording(tmp_path / "rec.npz", {"accel": np.random.default_rng(0).standard_normal(n),
                                                "speed": np.full(n, 100.0), "force": np.full(n, 1.0)}, rate=1000.0)
    out = [str(tmp_path / f) if not f.startswith("-") else f for f in flags]
    code = main(["fit", "texture", str(rec), "--accel", "accel", "--speed", "speed", "--force", "force", *out])
    assert code != 0 and message in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rec.npz"]   # refused before any work: nothing written


def test_models_resample_takes_a_tap_library(tmp_path: Path, capsys) -> None:
    # A 2 kHz surface with taps needed Python (the tap_player error named resample_tap_library); now one command.
    import numpy as np
    from scipy.signal import resample_poly

    from flowtex.cli.main import main
    from flowtex.datasets.taps import synthetic_tap_library
    from flowtex.io.taplib import read_tap_library, write_tap_library

    lib = synthetic_tap_library()
    src = write_tap_library(tmp_path / "taps.json", lib)
    assert main(["models", "resample", str(src), "--rate", "2000", "-o", str(tmp_path / "taps2k.json")]) == 0
    out = read_tap_library(tmp_path / "taps2k.json")
    assert out.sample_rate_hz == 2000.0
    np.testing.assert_array_equal(out.speeds, lib.speeds)
    expected = resample_poly(lib.transients, 2, 1, axis=1)       # scipy's polyphase resampler is the reference
    np.testing.assert_allclose(out.transients[:, :expected.shape[1]], expected[:, :out.transients.shape[1]], rtol=1e-12)
    assert main(["models", "resample", str(src), "--rate", "2000", "-o", str(tmp_path / "taps2k.xml")]) != 0
    assert "tap library is written as .json" in capsys.readouterr().err


@pytest.mark.parametrize(("surface", "line"), [
    ("    models: {data}/synthetic_texture.json\n", 7),
    ("    models: {data}/synthetic_texture_2k.json\n    taps: {data}/synthetic_taps.json\n", 8),
])
def test_scene_plan_refuses_a_file_at_another_rate_at_its_line(tmp_path: Path, surface: str, line: int) -> None:
    # A 2 kHz scene naming 1 kHz files was planned, then `scene run` failed naming a temporary graph file.
    from flowtex.errors import FlowtexError
    from flowtex.io.modelset import load_model_set, save_model_set
    from flowtex.scene.file import load_scene
    from flowtex.scene.plan import plan_scene

    data = Path(__file__).resolve().parents[1] / "graphs" / "data"
    ms = load_model_set(data / "synthetic_texture.json")
    ms.sample_rate = 2000.0                       # only the rate matters to the planner's check
    save_model_set(ms, tmp_path / "synthetic_texture_2k.json")
    for name in ("synthetic_taps.json",):
        (tmp_path / name).write_bytes((data / name).read_bytes())
    (tmp_path / "synthetic_texture.json").write_bytes((data / "synthetic_texture.json").read_bytes())
    scene = tmp_path / "s.yaml"
    scene.write_text("flowtex: 1\nname: s\nrate: 2000\ntrajectory: {speed: [50, 250], force: [0.5, 2.5]}\n"
                     "surfaces:\n  a:\n" + surface.format(data="."))
    with pytest.raises(FlowtexError, match=rf"s\.yaml:{line}:\d+: surface 'a': .* is sampled at 1000 Hz but the scene "
                                           r"runs at 2000 Hz; run 'flowtex models resample"):
        plan_scene(load_scene(scene))


def test_outputs_of_one_format_refuse_a_suffix_that_names_another(tmp_path: Path) -> None:
    # `fit friction -o mu.xml`, `fit taps -o t.xml` and `scene plan -o g.json` wrote JSON or YAML under those names.
    from flowtex.io.atomic import OutputError

    with pytest.raises(OutputError, match=r"-o .*mu\.xml: unknown output format '\.xml'; use \.json"):
        check_output(tmp_path / "mu.xml", option="-o", suffixes=(".json",))
    with pytest.raises(OutputError, match=r"unknown output format '\.json'; use \.yaml, \.yml"):
        check_output(tmp_path / "g.json", option="-o", suffixes=(".yaml", ".yml"))
    assert check_output(tmp_path / "MU.JSON", suffixes=(".json",)) == tmp_path / "MU.JSON"
    fifo = tmp_path / "pipe"                       # /dev/null and pipes have no suffix: accepted
    os.mkfifo(fifo)
    assert check_output(fifo, suffixes=(".json",)) == fifo
