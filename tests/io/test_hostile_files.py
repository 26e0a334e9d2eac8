"""Issue 17: memory and time bombs and silently-wrong files cost one line of text (exit 1), never memory or a traceback.

Every hostile file is built here, small: npy headers that claim more than they
hold, alias trees that would expand, deep nesting written as a short string.
Memory is bounded by measuring the peak of Python and numpy allocations
(tracemalloc) while the file is refused.
"""

from __future__ import annotations

import struct
import tracemalloc
import zipfile
from pathlib import Path

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.errors import FlowtexError
from flowtex.io.hatt import read_hatt_xml
from flowtex.io.modelset import load_model_set
from flowtex.io.recordings import load_recording
from flowtex.io.taplib import read_tap_library
from flowtex.limits import MAX_DEPTH, MAX_RECORDING_VALUES, excerpt
from tests.plugin_files import chain_graph

REPO = Path(__file__).resolve().parents[2]
MB = 2**20


def npy_header(shape: tuple[int, ...], descr: str = "<f8") -> bytes:
    """A version 1.0 npy header (magic, length, dict padded to 64 bytes) claiming ``shape``; no data follows."""
    text = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    text += " " * ((64 - (10 + len(text) + 1) % 64) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text.encode()


def refused(path_or_call, match: str, peak_mb: float = 30.0) -> str:
    """Run the reader, expect a one-line FlowtexError containing ``match``; the allocation peak stays under ``peak_mb``."""
    tracemalloc.start()
    try:
        with pytest.raises(FlowtexError) as info:
            path_or_call()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    msg = str(info.value)
    assert match in msg, msg
    assert len(msg.splitlines()) == 1 and len(msg) < 600, msg
    assert peak < peak_mb * MB, f"{peak / MB:.1f} MB allocated while refusing"
    return msg


def cli_one_line(capsys, argv: list[str], match: str) -> str:
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 1, err
    assert len(err.splitlines()) == 1 and len(err) < 600, err
    assert match in err, err
    return err


# -- npz headers: checked against the limit and the bytes present before anything is allocated --------------------

def test_npz_header_claiming_500_million_by_3_is_refused_by_the_limit(tmp_path):
    path = tmp_path / "bomb.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:  # the 11.6 MB original held zeros; the header is the bomb
        zf.writestr("acc.npy", npy_header((500_000_000, 3)))
    msg = refused(lambda: load_recording(path), f"{MAX_RECORDING_VALUES:,} numbers")
    assert str(path) in msg and "1,500,000,000" in msg


def test_npz_header_claiming_1e12_samples_in_64_bytes(tmp_path):
    path = tmp_path / "tiny.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("acc.npy", npy_header((10**12,)))
    assert path.stat().st_size < 400
    refused(lambda: load_recording(path), "1,000,000,000,000 numbers")


def test_npz_header_claiming_more_than_the_entry_holds_is_truncated(tmp_path):
    path = tmp_path / "short.npz"
    with zipfile.ZipFile(path, "w") as zf:  # within the limit, but only 64 of the claimed 8,000,000 bytes are there
        zf.writestr("acc.npy", npy_header((1_000_000,)) + bytes(64))
    refused(lambda: load_recording(path), "claims shape (1000000,) (8,000,000 bytes) but the entry holds 64 bytes")


def test_compressed_npz_member_whose_directory_claims_gigabytes_is_refused(tmp_path):
    data = npy_header((4,)) + np.arange(4.0).tobytes()
    path = tmp_path / "lying.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("acc.npy", data)
    raw = bytearray(path.read_bytes())
    central = raw.index(b"PK\x01\x02")
    raw[central + 24:central + 28] = struct.pack("<I", 0xFFFFFFF0)  # uncompressed size: ~4 GB
    path.write_bytes(bytes(raw))
    refused(lambda: load_recording(path), "unpacks to 4,294,967,280 bytes")


def test_npz_object_arrays_are_refused_without_unpickling(tmp_path):
    path = tmp_path / "obj.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("acc.npy", npy_header((2,), "|O") + b"\x80\x04N.")
    refused(lambda: load_recording(path), "dtype object")


# -- recordings: the documented rules (docs/recordings.md) ---------------------------------------------------------

@pytest.mark.parametrize(("arrays", "match"), [
    ({"acc": np.zeros(0)}, "signal 'acc' has no samples (the recording is empty)"),
    ({"acc": np.zeros((0, 3))}, "signal 'acc' has no samples"),
    ({"acc": np.zeros(1)}, "signal 'acc' has one sample; a recording needs at least 2"),
    ({"acc": np.ones(50) * (1 + 2j)}, "signal 'acc' is complex"),
    ({"acc": np.ones((3, 100))}, "shape (3, 100): 3 samples of 100 values each looks transposed"),
    ({"name": np.array(["a", "b"])}, "holds <U1 values, not numbers"),
    ({"time": np.array([0.0, 0.001, 0.002, 0.0015, 0.003])}, "'time' does not increase at sample 3 (0.002 then 0.0015"),
    ({"time": np.array([0.0, 0.001, 0.001, 0.002])}, "'time' does not increase at sample 2"),
    ({"time": np.r_[np.arange(10) * 0.001, 0.02 + np.arange(10) * 0.001]}, "jumps from 0.009 to 0.02 at sample 10"),
    ({"rate": np.float64(1000.0)}, "holds no signals"),
    ({"acc": np.ones(5), "units": np.array("[" * 100_000 + "]" * 100_000)}, "'units' must be JSON like"),
])
def test_recording_rules_npz(tmp_path, arrays, match):
    path = tmp_path / "r.npz"
    np.savez(path, **arrays)
    refused(lambda: load_recording(path), match)


def test_recording_rules_accept_what_they_document(tmp_path):
    path = tmp_path / "ok.npz"
    t = np.arange(100) * 0.001 + np.random.default_rng(0).uniform(-2e-4, 2e-4, 100)  # +-20 % jitter is not a gap
    np.savez(path, time=t, acc=np.ones((100, 3)), wide=np.ones((40, 20)), two=np.ones(100)[:, None] * [1, 2])
    with pytest.raises(FlowtexError, match="different lengths"):  # 40 samples of 20 values: not transposed, but short
        load_recording(path)
    np.savez(path, time=t, acc=np.ones((100, 3)), wide=np.ones((100, 20)), b=np.ones(100, bool), i=np.arange(100, dtype=np.int16))
    rec = load_recording(path)
    assert rec.arrays["wide"].shape == (100, 20) and rec.arrays["i"].dtype == np.float64 and rec.arrays["b"].sum() == 100


def test_duplicate_csv_columns_are_refused(tmp_path, capsys):
    path = tmp_path / "dup.csv"
    path.write_text("x,y,x\n1,2,3\n4,5,6\n")
    refused(lambda: load_recording(path), "column 'x' appears twice (columns 1 and 3)")
    path.write_text("p[0],p[1],p[0]\n1,2,3\n4,5,6\n")
    refused(lambda: load_recording(path), "column 'p[0]' appears twice")


def test_csv_time_column_jump_and_binary_csv(tmp_path):
    path = tmp_path / "t.csv"
    path.write_text("time,x\n" + "".join(f"{t},{t}\n" for t in (0.0, 0.001, 0.002, 0.005, 0.006)))
    refused(lambda: load_recording(path), "'time' jumps from 0.002 to 0.005 at sample 3, 3 times its median step")
    path.write_bytes(b"x\n1\n\xff\xfe\x00\n")
    refused(lambda: load_recording(path), "not UTF-8 text")
    path.write_text("x\n" + "1," * 600_000 + "\n")
    refused(lambda: load_recording(path), "longer than 1,048,576 characters")


def test_h5_with_string_data_is_refused(tmp_path):
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "s.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("acc", data=np.array([b"1.0", b"2.0", b"x"]))
    refused(lambda: load_recording(path), "dataset 'acc' holds |S3 values, not numbers")
    with h5py.File(path, "w") as fh:
        fh.create_dataset("acc", data=np.ones(10) * 1j)
    refused(lambda: load_recording(path), "signal 'acc' is complex")


def test_an_hdf5_file_whose_signals_are_in_groups_names_them(tmp_path):
    """Rigs often write /trial1/accel: flowtex reads the root's datasets and said only "holds no signals"."""
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "g.h5"
    with h5py.File(path, "w") as fh:
        fh.create_group("meta")
        trial = fh.create_group("trial1")
        for name in ("accel", "speed", "force", "position"):
            trial.create_dataset(name, data=np.zeros(10))
    refused(lambda: load_recording(path), "no dataset at the file's root; its signals are inside groups ('trial1/accel', "
                                          "'trial1/force', 'trial1/position', ...); flowtex reads one dataset per signal")
    with h5py.File(path, "w") as fh:
        fh.create_group("meta")
    refused(lambda: load_recording(path), "the recording holds no signals")  # nothing anywhere: as before


def test_bench_on_a_zero_length_recording(tmp_path, capsys):
    path = tmp_path / "empty.npz"
    np.savez(path, speed=np.zeros(0), rate=1000.0)
    cli_one_line(capsys, ["bench", str(REPO / "graphs" / "multirate_feedback.yaml"), "--input", str(path),
                          "--knob", "echo_delay.samples=1,2"], "has no samples (the recording is empty)")


# -- YAML: alias bombs, nesting, NUL bytes, ranges ---------------------------------------------------------------------

GRAPH = chain_graph("g: {type: gain, params: {k: 2}}", "echo_delay: {type: delay, params: {samples: 3}}", name="g")


def _graph(tmp_path, text: str) -> Path:
    path = tmp_path / "g.yaml"
    path.write_text(text)
    return path


def test_alias_bomb_in_a_node_parameter(tmp_path, capsys):
    lines = ["l0: &l0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"]
    lines += [f"l{i}: &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, 10)]  # 10**10 values if expanded
    text = GRAPH.replace("flowtex: 1\n", "flowtex: 1\n" + "\n".join(lines) + "\n").replace("{k: 2}", "{k: *l9}")
    path = _graph(tmp_path, text)
    err = cli_one_line(capsys, ["validate", str(path)], "this document holds more than 1,000,000 values, counting each alias (*name) in full")
    assert err.startswith(f"{path}:")


def test_small_alias_tree_is_quoted_as_an_excerpt(tmp_path, capsys):
    lines = ["- &l0 [1, 1, 1, 1, 1, 1, 1, 1, 1, 1]"] + [f"- &l{i} [{', '.join([f'*l{i - 1}'] * 10)}]" for i in range(1, 5)]
    text = GRAPH.replace("{k: 2}", "{k: *l4}")  # 10**5 values: under the limit; the anchors sit in the description
    path = _graph(tmp_path, text.replace("rate: 1000\n", "rate: 1000\ndescription:\n" + "\n".join(lines) + "\n"))
    cli_one_line(capsys, ["validate", str(path)], "parameter 'k' expected a number, got [[[[...], [...], [...], [...], [...], [...], ...]")
    assert excerpt(list(range(10**6))) == "[0, 1, 2, 3, 4, 5, ...]"
    assert len(excerpt("x" * 10**6)) == 60


@pytest.mark.parametrize(("text", "match"), [
    ("flowtex: 1\nx: " + "[" * 100_000 + "]" * 100_000 + "\n", f"nest more than {MAX_DEPTH} levels deep"),
    ("flowtex: 1\nx:\n" + "".join("  " * i + "- \n" for i in range(1, 200)), f"nest more than {MAX_DEPTH} levels deep"),
    ("flowtex: 1\nx: &a [1, *a]\n", "refers to the value that contains it"),
    ("flowtex: 1\n" + "a0: &a0 [1]\n" + "".join(f"a{i}: &a{i} [*a{i - 1}]\n" for i in range(1, 300)),
     f"aliases (*name) nest this document more than {MAX_DEPTH} levels deep"),
    ("flowtex: 1\nname: a\x00b\n", "g.yaml:2:8: character #x0000 is not allowed in YAML"),
], ids=["flow-100000-deep", "block-200-deep", "recursive-alias", "alias-chain-300", "nul-byte"])
def test_yaml_depth_recursion_and_nul(tmp_path, capsys, text, match):
    cli_one_line(capsys, ["validate", str(_graph(tmp_path, text))], match)


def test_every_out_of_range_is_refused_with_the_range(tmp_path, capsys):
    path = _graph(tmp_path, GRAPH.replace("{type: gain,", "{type: gain, every: 99999999999999999999,"))
    cli_one_line(capsys, ["validate", str(path)], "every must be a positive integer up to 1,000,000 (run every k ticks), "
                                                  "got 99999999999999999999")


def test_parameter_ranges_in_the_message(tmp_path, capsys):
    graph = str(REPO / "graphs" / "multirate_feedback.yaml")
    cli_one_line(capsys, ["validate", graph, "--set", "echo_delay.samples=10000000000"],
                 "parameter 'samples' must be <= 1e+07, got 1e+10 (expected int >= 1, <= 1e+07)")
    cli_one_line(capsys, ["validate", graph, "--set", "echo_delay.samples=" + "9" * 300], "must be <= 1e+07, got 1e+300")
    cli_one_line(capsys, ["validate", graph, "--set", "echo_gain.k=" + "9" * 400], "the integer 99999999999999999999... (400 digits) "
                                                                                   "is too large (at most 1e300)")
    cli_one_line(capsys, ["validate", graph, "--set", "echo_gain.k=" + "9" * 5000], "(5000 digits) is too large")
    path = _graph(tmp_path, GRAPH.replace("inputs: {x: {}}", "inputs: {x: {shape: [3]}}").replace("x -> g.x", "x -> sel.x")
                  .replace("g: {type: gain, params: {k: 2}}", "sel: {type: select, params: {index: 3000000000}}")
                  .replace("g.y -> echo_delay.x", "sel.y -> echo_delay.x"))
    cli_one_line(capsys, ["validate", str(path)], "parameter 'index' must be <= 2147483647 (the largest integer parameter)")


# -- JSON and XML documents ----------------------------------------------------------------------------------------------

def test_json_model_set_and_tap_library_nested_100000_deep(tmp_path):
    deep = "[" * 100_000 + "]" * 100_000
    ms = tmp_path / "m.json"
    ms.write_text('{"format": "flowtex-texture-models", "version": 1, "models": ' + deep + "}")
    refused(lambda: load_model_set(ms), f"nests lists or maps more than {MAX_DEPTH} levels deep")
    lib = tmp_path / "t.json"
    lib.write_text('{"format": "flowtex-tap-library", "version": 1, "taps": ' + deep + "}")
    refused(lambda: read_tap_library(lib), f"nests lists or maps more than {MAX_DEPTH} levels deep")
    ms.write_text('{"format": "flowtex-texture-models", "version": 1, "x": ' + "[" * 150 + "]" * 150 + "}")
    refused(lambda: load_model_set(ms), "more than 100 levels deep")  # deep, but under Python's recursion limit
    ms.write_text('{"format": "flowtex-texture-models", "version": 1, "sample_rate": 1e999}')
    refused(lambda: load_model_set(ms), "the number 1e999 is too large")


def _native_set(models: list[tuple[float, float]], **extra) -> str:
    import json

    entries = [{"speed": s, "force": f, "ar_lsf": [0.5, 1.5], "ma_lsf": [1.0], "variance": 1.0, "gain": 1.0} for s, f in models]
    return json.dumps({"format": "flowtex-texture-models", "version": 1, "material": "m", "sample_rate": 1000.0,
                       "ar_order": 2, "ma_order": 1, "models": entries, **extra})


def test_model_set_unknown_top_level_key_and_duplicate_vertices(tmp_path):
    path = tmp_path / "m.json"
    square = [(0.0, 0.0), (100.0, 0.0), (0.0, 2.0), (100.0, 2.0)]
    path.write_text(_native_set(square))
    assert load_model_set(path).num_models == 4
    path.write_text(_native_set(square, triangls=[[0, 1, 2]]))
    refused(lambda: load_model_set(path), "unknown top-level key 'triangls' (did you mean 'triangles'")
    path.write_text(_native_set(square + [(100.0, 2.0)]))
    refused(lambda: load_model_set(path), "models[3] and models[4] sit at the same point (100 mm/s, 2 N)")
    path.write_text(_native_set(square).replace('"ar_order": 2', '"ar_order": 1000000000000'))
    refused(lambda: load_model_set(path), "key 'ar_order' is 1000000000000; model orders run from 0 to 1000")


def test_xml_depth_and_entities_are_refused(tmp_path):
    path = tmp_path / "Models_x.xml"
    path.write_text("<modelSet>" + "<a>" * 100_000 + "</a>" * 100_000 + "</modelSet>")
    refused(lambda: read_hatt_xml(path), f"nests lists or maps more than {MAX_DEPTH} levels deep")
    laughs = '<?xml version="1.0"?><!DOCTYPE m [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;">]><modelSet>&b;</modelSet>'
    path.write_text(laughs)
    refused(lambda: load_model_set(path), "<!DOCTYPE> or <!ENTITY> declaration")
    path.write_text('<!DOCTYPE m SYSTEM "file:///etc/passwd"><modelSet/>')
    refused(lambda: read_hatt_xml(path), "flowtex reads plain XML only")


# -- DBC and fits -----------------------------------------------------------------------------------------------------

def test_dbc_signal_with_scale_0(tmp_path):
    from flowtex.io.dbc import load_dbc

    text = (REPO / "graphs" / "devices" / "example.dbc").read_text()
    path = tmp_path / "d.dbc"
    path.write_text(text.replace("SG_ Current : 0|16@1- (0.0001,0)", "SG_ Current : 0|16@1- (0,0)"))
    refused(lambda: load_dbc(path), "signal VoiceCoilCmd.Current has scale 0")


@pytest.mark.parametrize(("factor", "match"), [(1e300, "beyond any sensor's range (at most 100000 m/s^2)"),
                                               (1e-300, "below any sensor's resolution (at least 1e-09 m/s^2)")])
def test_fit_texture_accel_scaled_absurdly(tmp_path, capsys, factor, match):
    from flowtex.io.recordings import save_recording

    rng = np.random.default_rng(0)
    n = 4000
    path = tmp_path / "r.npz"
    save_recording(path, {"accel": rng.normal(size=n) * factor, "speed": np.full(n, 100.0), "force": np.full(n, 1.0)}, 1000.0)
    out = tmp_path / "o.json"
    cli_one_line(capsys, ["fit", "texture", str(path), "--speed", "speed", "--max-order", "4", "-o", str(out)], match)
    assert not out.exists()



@pytest.mark.parametrize(("verb", "units", "match"), [
    ("texture", {"speed": "m/s"}, "signal 'speed' is in 'm/s' (the file's units) but --speed takes mm/s; flowtex converts no "
                                  "unit: multiply it by 1000 and state its unit as mm/s"),
    ("texture", {"accel": "g"}, "signal 'accel' is in 'g' (the file's units) but --accel takes m/s^2; flowtex converts no "
                                "unit: multiply it by 9.80665 and state its unit as m/s^2"),
    ("friction", {"force": "mN"}, "signal 'force' is in 'mN' (the file's units) but --force takes N; flowtex converts no "
                                  "unit: multiply it by 0.001 and state its unit as N")])
def test_fit_signal_the_file_states_in_another_unit_is_refused(tmp_path, capsys, verb, units, match):
    """The fits take m/s^2, N and mm/s; a recording that states another unit for a signal is refused naming it and the
    factor (before, an acceleration stated in g was fitted as m/s^2, a surface 20 dB too quiet, and a speed in m/s was
    "no piece is moving ... check --speed is in mm/s" although the file said m/s). The unit written another way passes."""
    from flowtex.io.recordings import save_recording

    rng = np.random.default_rng(0)
    n = 8000
    force = np.repeat([0.5, 0.5, 2.0, 2.0], n // 4)  # four plateaus of 2 s: a model set needs a spread of points
    arrays = {"accel": rng.normal(size=n), "speed": np.repeat([60.0, 240.0, 60.0, 240.0], n // 4), "force": force,
              "friction": 0.3 * force + 0.01 * rng.normal(size=n)}
    path = tmp_path / "r.npz"
    out = tmp_path / "o.json"
    argv = (["fit", "texture", str(path), "--speed", "speed", "--force", "force", "--max-order", "4", "-o", str(out)] if verb == "texture" else
            ["fit", "friction", str(path), "--force", "force", "--friction-force", "friction", "-o", str(out)])
    save_recording(path, arrays, 1000.0, units=units)
    cli_one_line(capsys, argv, match)
    assert not out.exists()
    save_recording(path, arrays, 1000.0, units={"accel": "m/s/s", "speed": "mm/s", "force": "N", "friction": "N"})
    assert main(argv) == 0, capsys.readouterr().err
    assert out.exists()

def test_fit_compliance_zero_accel_and_force_1e30(tmp_path, capsys):
    from flowtex.datasets.patterns import stroking_recording
    from flowtex.io.recordings import save_recording

    rec = stroking_recording(0.5, seconds=1.0, k_g=0.5, seed=1)
    path = tmp_path / "s.npz"
    out = tmp_path / "c.json"
    argv = ["fit", "compliance", str(path), "--force", "force", "--accel", "accel", "-o", str(out)]
    save_recording(path, {"force": rec["force"], "accel": rec["accel"] * 0.0}, rec["rate"])
    cli_one_line(capsys, argv, "the acceleration (--accel) is 0 m/s^2 throughout the contact: no vibration was recorded")
    save_recording(path, {"force": rec["force"] * 1e30, "accel": rec["accel"]}, rec["rate"])
    cli_one_line(capsys, argv, "peak force 3.03e+30 N is beyond any sensor's range (at most 10000 N)")
    assert not out.exists()
    from flowtex.fit.compliance import estimate_compliance

    with pytest.raises(FlowtexError, match="peak force 3.03e[+]30 N is beyond"):  # the library refuses it too
        estimate_compliance(rec["force"] * 1e30, rec["accel"], rec["rate"], k_g=0.5)


def test_csv_and_h5_stop_at_the_value_limit(tmp_path, monkeypatch):
    import flowtex.io.recordings as recordings
    import flowtex.limits as limits

    monkeypatch.setattr(limits, "MAX_RECORDING_VALUES", 1000)  # the limit, scaled down so the test file stays small
    monkeypatch.setattr(recordings, "MAX_RECORDING_VALUES", 1000)
    path = tmp_path / "long.csv"
    path.write_text("a,b\n" + "1,2\n" * 600)
    refused(lambda: load_recording(path), "the CSV table (so far) holds 1,002 numbers; flowtex reads recordings of up to 1,000")
    h5py = pytest.importorskip("h5py")
    path = tmp_path / "long.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("a", data=np.zeros((400, 3)))
    refused(lambda: load_recording(path), "dataset 'a' (shape (400, 3)) holds 1,200 numbers")
    # two datasets within the limit each, over it together: the message counted the total as the second's own, and the
    # first was read (allocated) before the second's header was looked at
    path = tmp_path / "two.h5"
    with h5py.File(path, "w") as fh:
        fh.create_dataset("a", data=np.zeros(600))
        fh.create_dataset("b", data=np.zeros(600))
    read = []
    monkeypatch.setattr(recordings, "numeric_signal", lambda arr, *a: read.append(arr) or arr)
    refused(lambda: load_recording(path), "dataset 'b' (shape (600,)), with the datasets before it, holds 1,200 numbers")
    assert read == []
    np.savez(tmp_path / "two.npz", a=np.zeros(600), b=np.zeros(600))
    refused(lambda: load_recording(tmp_path / "two.npz"), "entry 'b' (shape (600,)), with the entries before it, holds 1,200 "
                                                          "numbers")


def test_oversized_text_files_are_refused_before_reading(tmp_path, capsys):
    from flowtex.io.dbc import load_dbc

    graph = tmp_path / "huge.yaml"
    with graph.open("wb") as fh:  # sparse: 2 MiB of nothing, refused by its size before a byte is parsed
        fh.truncate(2 * MB)
    cli_one_line(capsys, ["validate", str(graph)], "graph file is 2.0 MiB; flowtex reads graph files up to 1 MiB")
    dbc = tmp_path / "huge.dbc"
    with dbc.open("wb") as fh:
        fh.truncate(5 * MB)
    refused(lambda: load_dbc(dbc), "DBC file is 5.0 MiB; flowtex reads such files up to 4 MiB")
