"""Property-based fuzzing (hypothesis) of every reader (issue 17): any input ends in success or a FlowtexError.

Each reader gets a valid file of its kind, built here, and mutated: tokens of
its grammar inserted, spans deleted or duplicated, bytes replaced, the file
truncated. Recordings are also generated structurally (forged npy headers,
dtypes, HDF5 datasets). The property: the reader returns, or raises
:class:`FlowtexError` whose message is short and names the file (one line; a
graph or scene may list several problems, one per line). Anything else, a
Python exception or an example slower than its deadline, fails. Budgets are
explicit and derandomised so the whole module stays within seconds in CI.
"""

from __future__ import annotations

import os
import struct
import zipfile
from pathlib import Path

import can
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.errors import FlowtexError
from flowtex.graph.compiled import check_graph
from flowtex.io.canlog import SessionWriter, read_session, read_session_checked
from flowtex.io.canmap import load_map
from flowtex.io.dbc import load_dbc
from flowtex.io.hatt import write_hatt_xml
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.io.patternfile import Pattern, read_pattern, write_pattern
from flowtex.io.recordings import load_recording, save_recording
from flowtex.io.taplib import read_tap_library, write_tap_library
from flowtex.models.taps import TapLibrary
from flowtex.scene.file import load_scene

REPO = Path(__file__).resolve().parents[2]
DBC = REPO / "graphs" / "devices" / "example.dbc"
GIN = {"position": 3, "normal_force": 1}
GOUT = {"vibration": 1, "force": 3}


def budget(examples: int, deadline_ms: int = 2000):
    """A fixed, reproducible fuzzing budget for one reader."""
    return settings(max_examples=examples, deadline=deadline_ms, derandomize=True, database=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture, HealthCheck.data_too_large])


YAML_TOKENS = [b":", b"- ", b"[", b"]", b"{", b"}", b"&a ", b"*a", b"<<: *a\n", b"\n", b"  ", b"!!python/object:os.system ",
               b"\x00", b"1e999", b"99999999999999999999", b"-1", b"null", b"'", b'"', b"#", b"\t", b"%YAML 1.1\n", b"---\n",
               b"? ", b"|\n", b"\xff", b"nodes:", b"type: delay", b"every: 0", b"samples: 1e10"]
JSON_TOKENS = [b"{", b"}", b"[", b"]", b",", b":", b'"', b"NaN", b"Infinity", b"1e999", b"-0", b"null", b"true",
               b"99999999999999999999999", b"[[[[[[[[", b"\\u0000", b"\xff", b'"triangls"', b'"models"', b"1e-320"]
XML_TOKENS = [b"<", b">", b"</", b"/>", b"<value>", b"</value>", b"<model>", b"</model>", b"&amp;", b"&x;", b"<!DOCTYPE a>",
              b"<![CDATA[", b"]]>", b"nan", b"1e999", b"-1", b"\x00", b"\xff", b"<tri>", b"<!--"]
DBC_TOKENS = [b"BO_ ", b" SG_ ", b"|", b"@1+", b"@0-", b"(0,0)", b"(1e999,0)", b"[", b"]", b'"', b":", b"\n", b"64|", b"VAL_ ",
              b"SIG_VALTYPE_ ", b"-1", b"\xff"]
CSV_TOKENS = [b",", b"\n", b"#", b"# rate: ", b"# units: ", b"nan", b"inf", b"1e999", b"-", b"x[0]", b"time", b'"', b"\x00",
              b"\xff", b"1j", b"\r"]


@st.composite
def mutated(draw, base: bytes, tokens: list[bytes]) -> bytes:
    """``base`` after 1-6 random edits: insert a token, delete or duplicate a span, replace a byte, truncate."""
    data = bytearray(base)
    for _ in range(draw(st.integers(1, 6))):
        kind = draw(st.integers(0, 4))
        i = draw(st.integers(0, len(data)))
        if kind == 0:
            data[i:i] = draw(st.sampled_from(tokens)) * draw(st.sampled_from([1, 1, 2, 50]))
        elif kind == 1:
            del data[i:i + draw(st.integers(1, 60))]
        elif kind == 2 and i < len(data):
            data[i] = draw(st.integers(0, 255))
        elif kind == 3:
            del data[i:]
        else:
            j = draw(st.integers(0, len(data)))
            data[i:i] = data[j:j + draw(st.integers(1, 200))]
    return bytes(data)


def ends_cleanly(call, path: Path, lines_allowed: int = 1):
    """Run ``call``; a FlowtexError must be short, name ``path`` on each line, and have at most ``lines_allowed`` lines."""
    try:
        return call()
    except FlowtexError as exc:
        msg = str(exc)
        lines = msg.splitlines()
        assert 1 <= len(lines) <= lines_allowed, msg[:2000]
        assert all(len(line) < 1000 for line in lines), msg[:2000]
        assert all(path.name in line or line.startswith("--set") or "example.dbc" in line for line in lines), msg[:2000]
        return None


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


# -- YAML readers ----------------------------------------------------------------------------------------------------

GRAPH_BASE = (REPO / "graphs" / "multirate_feedback.yaml").read_bytes()
SCENE_BASE = (REPO / "graphs" / "scene_two_surfaces.yaml").read_bytes()
MAP_BASE = (REPO / "graphs" / "devices" / "example_map.yaml").read_bytes()


@budget(50)
@given(data=mutated(GRAPH_BASE, YAML_TOKENS))
def test_graph_yaml(folder, data):
    path = folder / "g.yaml"
    path.write_bytes(data)
    ends_cleanly(lambda: check_graph(path), path, lines_allowed=200)


@budget(40)
@given(data=mutated(SCENE_BASE, YAML_TOKENS))
def test_scene_yaml(folder, data):
    path = folder / "scene.yaml"  # parsing a scene does not open the files it names
    path.write_bytes(data)
    ends_cleanly(lambda: load_scene(path), path, lines_allowed=200)


@pytest.fixture(scope="module")
def dbc():
    return load_dbc(DBC)


@budget(40)
@given(data=mutated(MAP_BASE, YAML_TOKENS))
def test_device_map(folder, dbc, data):
    path = folder / "map.yaml"
    path.write_bytes(data)
    ends_cleanly(lambda: load_map(path, dbc, DBC, GIN, GOUT), path, lines_allowed=200)


@budget(25, 4000)
@given(data=mutated(DBC.read_bytes(), DBC_TOKENS))
def test_dbc_binding(folder, data):
    path = folder / "example.dbc"
    path.write_bytes(data)
    db = ends_cleanly(lambda: load_dbc(path), path)
    if db is not None:
        mp = folder / "bound.yaml"
        mp.write_bytes(MAP_BASE)
        ends_cleanly(lambda: load_map(mp, db, path, GIN, GOUT), path, lines_allowed=200)


# -- JSON and XML documents --------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def small_set():
    return synthetic_model_set([50.0, 150.0, 250.0], [0.5, 1.0, 1.7], ar_order=4, ma_order=3)


@pytest.fixture(scope="module")
def bases(folder, small_set):
    """Valid files of each JSON/XML kind, as bytes."""
    pat = Pattern(1000.0, np.array([1.0, 0.0, 0.0]), np.zeros(3), np.array([1.0, 3.0, 5.0]), np.array([0.5, 0.7, 0.6]),
                  [np.array([1.0, 0.2])] * 3, [np.array([1.0, -0.5])] * 3)
    lib = TapLibrary(np.array([20.0, 50.0]), np.sin(np.arange(2 * 32).reshape(2, 32) * 0.3), 1000.0)
    return {"json": save_model_set(small_set, folder / "base.json").read_bytes(),
            "xml": write_hatt_xml(small_set, folder / "base.xml").read_bytes(),
            "pattern": write_pattern(folder / "pbase.json", pat).read_bytes(),
            "taps": write_tap_library(folder / "tbase.json", lib).read_bytes()}


@budget(40)
@given(data=st.data())
def test_model_set_json(folder, bases, data):
    path = folder / "m.json"
    path.write_bytes(data.draw(mutated(bases["json"], JSON_TOKENS)))
    ends_cleanly(lambda: load_model_set(path), path)


@budget(40)
@given(data=st.data())
def test_model_set_xml(folder, bases, data):
    path = folder / "m.xml"
    path.write_bytes(data.draw(mutated(bases["xml"], XML_TOKENS)))
    ends_cleanly(lambda: load_model_set(path), path)


@budget(30)
@given(data=st.data())
def test_pattern_file(folder, bases, data):
    path = folder / "p.json"
    path.write_bytes(data.draw(mutated(bases["pattern"], JSON_TOKENS)))
    ends_cleanly(lambda: read_pattern(path), path)


@budget(30)
@given(data=st.data())
def test_tap_library(folder, bases, data):
    path = folder / "t.json"
    path.write_bytes(data.draw(mutated(bases["taps"], JSON_TOKENS)))
    ends_cleanly(lambda: read_tap_library(path), path)


# -- recordings --------------------------------------------------------------------------------------------------------

def _npy(shape, descr: str, payload: int) -> bytes:
    text = f"{{'descr': '{descr}', 'fortran_order': False, 'shape': {tuple(shape)!r}, }}"
    text += " " * ((64 - (10 + len(text) + 1) % 64) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(text)) + text.encode() + bytes(payload)


@budget(40)
@given(members=st.lists(st.tuples(
    st.sampled_from(["acc", "time", "rate", "units", "x"]),
    st.lists(st.sampled_from([0, 1, 2, 3, 17, 100, 10**6, 2**40]), max_size=3),
    st.sampled_from(["<f8", ">f4", "<i2", "|b1", "<c16", "|O", "<U3", "|S2", "|V8", "<M8[s]", "<f8"]),
    st.integers(0, 2000)), min_size=1, max_size=4), compressed=st.booleans())
@pytest.mark.filterwarnings("ignore:Duplicate name")  # duplicate members are part of the fuzz
def test_npz_forged_headers(folder, members, compressed):
    path = folder / "forged.npz"
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED if compressed else zipfile.ZIP_STORED) as zf:
        for name, shape, descr, payload in members:
            zf.writestr(f"{name}.npy", _npy(shape, descr, payload))
    ends_cleanly(lambda: load_recording(path), path)


@budget(40)
@given(data=st.data())
def test_npz_mutated(folder, data):
    base = folder / "base.npz"
    n = 64
    np.savez(base, time=np.arange(n) / 1000.0, acc=np.ones((n, 3)), rate=np.float64(1000.0), units=np.array('{"acc": "m/s^2"}'))
    path = folder / "m.npz"
    path.write_bytes(data.draw(mutated(base.read_bytes(), [b"PK", b"\x00" * 8, b"\xff" * 4, b"NUMPY"])))
    ends_cleanly(lambda: load_recording(path), path)


@budget(40)
@given(data=st.data())
def test_csv_mutated(folder, data):
    base = folder / "base.csv"
    n = 20
    save_recording(base, {"time": np.arange(n) / 1000.0, "acc": np.ones((n, 2)), "f": np.linspace(0, 1, n)}, 1000.0, {"f": "N"})
    path = folder / "m.csv"
    path.write_bytes(data.draw(mutated(base.read_bytes(), CSV_TOKENS)))
    ends_cleanly(lambda: load_recording(path), path)


@budget(25)
@given(datasets=st.lists(st.tuples(
    st.sampled_from(["acc", "time", "x"]),
    st.sampled_from(["f8", "i4", "c16", "S3", "bool", "f2"]),
    st.lists(st.integers(0, 40), min_size=0, max_size=2)), min_size=0, max_size=3),
    rate=st.sampled_from([None, 1000.0, -1.0, "fast", float("nan")]), truncate=st.integers(0, 3))
def test_h5_structured(folder, datasets, rate, truncate):
    h5py = pytest.importorskip("h5py")
    path = folder / "r.h5"
    with h5py.File(path, "w") as fh:
        for name, dtype, shape in datasets:
            if name in fh:
                continue
            fh.create_dataset(name, data=np.zeros(shape, dtype=np.dtype(dtype)) if dtype != "S3" else np.full(shape, b"abc"))
        if rate is not None:
            fh.attrs["rate"] = rate
    if truncate:  # a cut-off file: the HDF5 library must report it, not crash
        data = path.read_bytes()
        path.write_bytes(data[: len(data) * truncate // 4])
    ends_cleanly(lambda: load_recording(path), path)


# -- CAN session logs ----------------------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def blf(folder):
    path = folder / "base.blf"
    w = SessionWriter(path)
    for i in range(40):
        w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=0x100 + i % 3, data=bytes([i] * 8), is_extended_id=False), i % 2 == 0)
    w.close()
    return path.read_bytes()


@budget(30)
@given(data=st.data())
def test_blf_replay(folder, blf, data):
    path = folder / "m.blf"
    path.write_bytes(data.draw(mutated(blf, [b"LOGG", b"LOBJ", b"\xff" * 4, b"\x00" * 16, b"\x78\x9c"])))
    ends_cleanly(lambda: list(read_session(path)), path)


TEXT_LOG_TOKENS = [b"(", b")", b"#", b"##", b"R", b"T", b" Rx ", b" Tx ", b" d ", b" r ", b"x", b"nan", b"1e400", b"-",
                   b"FFFFFFFF", b"\n", b"\r\n", b" ", b"\t", b"\xff", b"\x00", b"CANFD", b"base dec", b"ErrorFrame", b"15"]


@pytest.fixture(scope="module")
def text_logs(folder):
    """A .log and an .asc of 40 frames as flowtex records them (standard, extended and CAN FD ids, both directions)."""
    out = {}
    for suffix in (".log", ".asc"):
        path = folder / f"base{suffix}"
        w = SessionWriter(path)
        for i in range(40):
            w.write(can.Message(timestamp=1000.0 + i * 1e-3, arbitration_id=(0x100 + i % 3) if i % 5 else 0x1234567,
                                is_extended_id=i % 5 == 0, data=bytes([i] * (8 if i % 7 else 12)), is_fd=i % 7 == 0), i % 2 == 0)
        w.close()
        out[suffix] = path.read_bytes()
    return out


@budget(40)
@given(suffix=st.sampled_from([".log", ".asc"]), data=st.data())
def test_text_log_replay(folder, text_logs, suffix, data):
    """A mutated text log is read or refused at a line of it; what is read names a line of the file for every frame."""
    path = folder / f"m{suffix}"
    raw = data.draw(mutated(text_logs[suffix], TEXT_LOG_TOKENS))
    path.write_bytes(raw)
    got = ends_cleanly(lambda: read_session_checked(path), path)
    if got is None:
        return
    frames, completeness = got
    lines = raw.count(b"\n") + 1
    assert len(completeness.lines) == len(frames) and all(1 <= n <= lines for n in completeness.lines)
    assert all(m.arbitration_id <= (0x1FFFFFFF if m.is_extended_id else 0x7FF) for m in frames)


# -- special files: FIFOs and devices under any reader's name ---------------------------------------------------------

SPECIAL_READERS = {
    ".npz": load_recording, ".csv": load_recording, ".wav": load_recording, ".h5": load_recording,
    ".json": load_model_set, ".xml": load_model_set, ".yaml": check_graph, ".dbc": load_dbc, ".blf": lambda p: list(read_session(p)),
    ".log": lambda p: list(read_session(p)), ".pattern.json": read_pattern, ".taps.json": read_tap_library,
}


@pytest.fixture(scope="module")
def special_targets(folder):
    """A FIFO nobody writes to and the endless devices; each is reached through a link with a reader's suffix."""
    fifo = folder / "special.fifo"
    if not fifo.exists():
        os.mkfifo(fifo)
    return [str(fifo)] + [d for d in ("/dev/zero", "/dev/urandom", "/dev/null") if os.path.exists(d)]


@budget(40, 5000)
@given(suffix=st.sampled_from(sorted(SPECIAL_READERS)), which=st.integers(0, 3), via_link=st.booleans())
def test_special_files_end_cleanly_and_fast(folder, special_targets, suffix, which, via_link):
    """A reader given a FIFO or a device returns a one-line refusal within the deadline: nothing blocks, nothing reads on."""
    target = Path(special_targets[which % len(special_targets)])
    path = folder / f"sp{which}{'l' if via_link else ''}{suffix}"
    if not os.path.lexists(path):
        mid = folder / f"mid{which}"  # a link to a link
        if via_link and not os.path.lexists(mid):
            os.symlink(target, mid)
        os.symlink(mid if via_link else target, path)
    with pytest.raises(FlowtexError) as info:
        SPECIAL_READERS[suffix](path)
    msg = str(info.value)
    assert len(msg.splitlines()) == 1 and "not a regular file" in msg, msg
