"""Nothing unbounded (issue 27, section 3): special files, a WAV claiming 600 million samples, port shapes, and the
options --seeds and --knob. Every hostile file is built here, small (the WAV is sparse: a few KB on disk)."""

from __future__ import annotations

import os
import struct
import textwrap
import threading

import numpy as np
import pytest
from scipy.io import wavfile

from flowtex.errors import FlowtexError
from flowtex.graph.compiled import load_graph
from flowtex.io.modelset import load_model_set
from flowtex.io.recordings import load_recording, save_recording
from flowtex.limits import MAX_BUFFER_VALUES, MAX_CONFIGURATIONS, MAX_PORT_VALUES, MAX_RECORDING_VALUES, MAX_SEEDS
from tests.io.test_hostile_files import cli_one_line, refused


def wav_header(channels: int, bits: int, data_bytes: int, rate: int = 8000) -> bytes:
    """A PCM WAV header (RIFF, fmt, data) whose data chunk claims ``data_bytes``."""
    block = channels * bits // 8
    fmt = struct.pack("<HHIIHH", 1, channels, rate, rate * block, block, bits)
    return (b"RIFF" + struct.pack("<I", 36 + data_bytes) + b"WAVE" + b"fmt " + struct.pack("<I", 16) + fmt
            + b"data" + struct.pack("<I", data_bytes))


def test_a_sparse_wav_claiming_600_million_samples_is_refused_before_reading(tmp_path):
    path = tmp_path / "bomb.wav"
    claimed = 600_000_000  # 16-bit mono: 1.2 GB of data
    with open(path, "wb") as fh:
        fh.write(wav_header(1, 16, 2 * claimed))
        fh.truncate(44 + 2 * claimed)  # sparse: the size is claimed, almost nothing is on disk
    msg = refused(lambda: load_recording(path), f"holds {claimed:,} numbers")
    assert msg.startswith(str(path)) and f"{MAX_RECORDING_VALUES:,}" in msg


def test_a_wav_with_zero_frames_is_refused(tmp_path, capsys):
    path = tmp_path / "empty.wav"
    wavfile.write(path, 8000, np.zeros((0, 2), dtype=np.int16))
    refused(lambda: load_recording(path), "has no samples")
    cli_one_line(capsys, ["plot", str(path), "-o", str(tmp_path / "p.png")], "has no samples")


def test_a_wav_at_the_limit_is_read_as_written(tmp_path):
    """The header walk reads what scipy reads: a stereo 16-bit WAV round-trips (samples / 32768)."""
    x = (np.arange(200, dtype=np.int16).reshape(100, 2) - 100) * 300
    wavfile.write(tmp_path / "ok.wav", 8000, x)
    rec = load_recording(tmp_path / "ok.wav")
    assert rec.rate == 8000.0 and np.array_equal(rec.arrays["ch1"], x[:, 1] / 32768.0)


@pytest.fixture
def specials(tmp_path):
    """A FIFO (no writer ever opens it), and links named like inputs that point to /dev/zero and /dev/urandom."""
    fifo = tmp_path / "fifo"
    os.mkfifo(fifo)
    out = {"fifo": fifo}
    for dev in ("zero", "urandom"):
        if os.path.exists(f"/dev/{dev}"):
            out[dev] = tmp_path / dev
            os.symlink(f"/dev/{dev}", out[dev])
    return out


def _as(special, suffix):
    """``special`` under a name ending in ``suffix`` (a link), so every reader is reached by its suffix."""
    link = special.with_name(special.name + suffix)
    if not link.exists():
        os.symlink(special, link)
    return link


READERS = {
    "recording npz": (".npz", lambda p: load_recording(p), "the recording is"),
    "recording csv": (".csv", lambda p: load_recording(p), "the recording is"),
    "recording wav": (".wav", lambda p: load_recording(p), "the recording is"),
    "model set": (".json", lambda p: load_model_set(p), "the model file is"),
    "graph yaml": (".yaml", lambda p: load_graph(p), "the graph file is"),
}


@pytest.mark.parametrize("reader", list(READERS))
def test_special_files_are_refused_before_they_are_opened(specials, reader):
    """A thread runs the reader so that a blocked open (a FIFO) fails the test instead of hanging it."""
    suffix, call, match = READERS[reader]
    for name, special in specials.items():
        path = _as(special, suffix)
        result: list[BaseException | None] = []

        def run(path=path, result=result):
            try:
                call(path)
                result.append(None)
            except BaseException as exc:  # handed to the test thread
                result.append(exc)

        t = threading.Thread(target=run, daemon=True)
        t.start()
        t.join(30)
        if t.is_alive():  # unblock the reader stuck in open() so the daemon thread can end
            with open(special, "wb") if name == "fifo" else open(os.devnull, "wb"):
                pass
            pytest.fail(f"{reader} blocked on {name}")
        assert isinstance(result[0], FlowtexError), (name, result)
        msg = str(result[0])
        assert match in msg and "not a regular file" in msg and len(msg.splitlines()) == 1, msg


def test_cli_refuses_dev_zero_as_a_graph_dbc_and_map(specials, capsys, tmp_path):
    if "zero" not in specials:
        pytest.skip("no /dev/zero")
    zero = specials["zero"]
    cli_one_line(capsys, ["validate", str(_as(zero, ".yaml"))], "not a regular file")
    cli_one_line(capsys, ["validate", str(_as(zero, ".dbc"))], "not a regular file")
    cli_one_line(capsys, ["run", str(_as(zero, ".yaml")), "-i", str(tmp_path / "x.npz"), "-o", str(tmp_path / "o.npz")],
                 "not a regular file")


def _graph(tmp_path, shape: str, plugin: str | None = None) -> object:
    text = f"""\
        flowtex: 1
        name: wide
        rate: 1000
        inputs:
          x: {{shape: {shape}}}
        nodes:
          k: {{type: {plugin or 'gain'}{'' if plugin else ', params: {k: 2}'}}}
        edges:
          - x -> k.x
        outputs:
          y: k.y
        """
    (tmp_path / "g.yaml").write_text(textwrap.dedent(text))
    return tmp_path / "g.yaml"


def test_a_graph_input_beyond_the_port_limit_is_refused_at_its_line(tmp_path, capsys):
    g = _graph(tmp_path, "[100000, 100000]")
    msg = cli_one_line(capsys, ["validate", str(g)], "carries 10,000,000,000 values per tick")
    assert msg.startswith(f"{g}:5:") and f"{MAX_PORT_VALUES:,}" in msg
    g = _graph(tmp_path, f"[{MAX_PORT_VALUES}]")  # at the limit: fine
    assert load_graph(g).inputs["x"].shape == (MAX_PORT_VALUES,)


def test_buffers_beyond_the_limit_are_refused_before_allocating(tmp_path):
    """60,000 values a tick in and out of one gain, 1,024 rows: 122,880,000 values, under 2^27; 4,096 rows are over."""
    g = _graph(tmp_path, "[60000]")
    assert 60000 * 2 * 1024 <= MAX_BUFFER_VALUES < 60000 * 2 * 4096
    refused(lambda: load_graph(g, block_rows=4096), f"would hold {60000 * 2 * 4096:,} values", peak_mb=60)


def test_a_plugin_port_of_a_billion_values_is_refused(tmp_path, capsys):
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "huge.py").write_text(textwrap.dedent("""\
        import numpy as np
        from numba import njit
        from flowtex.node_api import Node, NodeState, Port

        @njit(cache=False)
        def huge_kernel(p, s, si, x, y):
            pass

        class Huge(Node):
            type_name = "huge"
            inputs = {"x": Port(None, "*", "signal")}
            outputs = {"y": Port((10**9,), "", "too wide")}
            kernel = huge_kernel

            def build(self, inputs, outputs):
                return NodeState()
        """))
    g = _graph(tmp_path, "[3]", plugin="huge")
    for verb in (["validate", str(g)], ["graph", str(g)]):
        msg = cli_one_line(capsys, verb + ["--plugins", str(tmp_path / "plugins")], "1,000,000,000 values per tick")
        assert "output 'y'" in msg and f"{MAX_PORT_VALUES:,}" in msg, msg  # at the plugin's declaration (nodecheck)


def test_compare_seeds_and_bench_knobs_are_bounded(tmp_path, capsys):
    cli_one_line(capsys, ["compare", "s.json", "r.npz", "--seeds", "1000000"], f"valid 1..{MAX_SEEDS}")
    save_recording(tmp_path / "in.npz", {"x": np.zeros(10)}, rate=1000.0)
    (tmp_path / "g.yaml").write_text(textwrap.dedent("""\
        flowtex: 1
        name: g
        rate: 1000
        inputs: {x: {}}
        nodes: {k: {type: gain, params: {k: 1}}}
        edges: [x -> k.x]
        outputs: {y: k.y}
        """))
    values = ",".join(str(v) for v in range(30000))
    msg = cli_one_line(capsys, ["bench", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "in.npz"), "--knob", f"k.k={values}"],
                       f"30,000 configurations; bench runs at most {MAX_CONFIGURATIONS}")
    assert msg.startswith("--knob")
    msg = cli_one_line(capsys, ["bench", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "in.npz"), "--knob", "k.k=1,2,3,4,5,6,7,8",
                                "--knob", "k.every=" + ",".join(str(v) for v in range(1, 41))], "8 (k.k) x 40 (k.every) = 320")
    # a --reference without '=' was reported as a '--set' the command line never had
    msg = cli_one_line(capsys, ["bench", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "in.npz"), "--knob", "k.k=1,2",
                                "--reference", "k.k"], "expected --reference NODE.PARAM=VALUE")
    assert msg.startswith("--reference k.k: ")
