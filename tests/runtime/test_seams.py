"""The typed seams between graph, runtime and CAN I/O: LiveConfig, CanIO's public compiled codec, the tick-program protocol."""

from __future__ import annotations

import ast
import dataclasses
import inspect
import re
from pathlib import Path

import numpy as np
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.errors import FlowtexError
from flowtex.graph.compiled import Graph, load_graph
from flowtex.graph.program import TickProgram
from flowtex.io.codec_tables import TableEncoder
from flowtex.runtime.buses import BusError
from flowtex.runtime.canio import CanIO, load_io
from flowtex.runtime.live import run_live
from flowtex.runtime.liveconfig import LiveConfig

REPO = Path(__file__).resolve().parents[2]
CANIO = REPO / "flowtex" / "runtime" / "canio.py"


# --- LiveConfig ------------------------------------------------------------------------------------
def test_run_live_takes_a_live_config(setup):  # noqa: F811
    config = LiveConfig(DBC, setup / "m.yaml", simulate=setup / "rec.npz", max_ticks=40, status=None, seed=7, show=["force"])
    r = run_live(load_graph(setup / "g.yaml"), config)
    assert r.error is None and r.ticks == 40 and r.frames_out == 40 * 2  # two actuator messages a tick
    assert r.device.frames_received == 40 * 2 + 2  # plus the safe values at exit
    assert config.show == ("force",)  # sequences are kept as tuples: the config cannot change under a running session
    with pytest.raises(dataclasses.FrozenInstanceError):
        config.max_ticks = 5  # type: ignore[misc]
    with pytest.raises(TypeError, match="run_live takes a LiveConfig, got dict"):
        run_live(load_graph(setup / "g.yaml"), {"dbc_path": DBC})  # type: ignore[arg-type]


@pytest.mark.parametrize("option,value,flag", [
    ("duration_s", 0, "--duration"), ("duration_s", -1.5, "--duration"), ("duration_s", float("nan"), "--duration"),
    ("duration_s", "2", "--duration"), ("max_ticks", 0, "max_ticks"), ("max_ticks", 2.5, "max_ticks"),
    ("rt_priority", "80", "--rt-priority"), ("rt_priority", 80.0, "--rt-priority"), ("rt_cpu", 1.0, "--cpu"),
    ("seed", -1, "--seed"), ("seed", 2**63, "--seed"), ("seed", 1.5, "--seed"), ("bitrate", 0, "--bitrate"),
    ("dbc_path", None, "--dbc"), ("map_path", "", "--map"),
])
def test_a_bad_option_is_one_line_naming_it(option, value, flag):
    base = {"dbc_path": "dev.dbc", "map_path": "map.yaml", "simulate": "rec.npz"}
    with pytest.raises(FlowtexError) as e:
        LiveConfig(**{**base, option: value})
    text = str(e.value)
    assert "\n" not in text and text.startswith(f"live option {option} ({flag}) = {value!r}: "), text


def test_options_that_need_each_other():
    with pytest.raises(FlowtexError, match=r"^live option drop \(drop\) = .*only applies to a simulated device"):
        LiveConfig("dev.dbc", "map.yaml", bus="virtual", drop={"ToolForce": (0, None)})
    with pytest.raises(BusError, match=r"^no --bus given .* and no --simulate RECORDING$"):
        LiveConfig("dev.dbc", "map.yaml")
    with pytest.raises(BusError, match=r"^--simulate runs the device on a 'virtual' bus in this process; drop --bus 'socketcan:can0'"):
        LiveConfig("dev.dbc", "map.yaml", bus="socketcan:can0", simulate="rec.npz")
    with pytest.raises(BusError, match=r"^--bus ':can0': expected INTERFACE\[:CHANNEL\]"):
        LiveConfig("dev.dbc", "map.yaml", bus=":can0")
    with pytest.raises(BusError, match=r"^--bus 'socketcand:can0@host:x1': port 'x1' is not a number"):
        LiveConfig("dev.dbc", "map.yaml", bus="socketcand:can0@host:x1")
    LiveConfig("dev.dbc", "map.yaml", bus="virtual:private", simulate="rec.npz")  # a named virtual channel is fine
    ok = LiveConfig("dev.dbc", "map.yaml", simulate="rec.npz", drop={"ToolForce": (0, None)}, seed=np.int64(3), rt_cpu=0)
    with pytest.raises(FlowtexError, match="max_ticks"):  # a copy is checked again
        dataclasses.replace(ok, max_ticks=0)


def test_tick_limit_is_the_shorter_of_duration_and_max_ticks():
    c = LiveConfig("dev.dbc", "map.yaml", bus="virtual")
    assert c.tick_limit(1000.0) is None
    assert dataclasses.replace(c, duration_s=0.25).tick_limit(1000.0) == 250
    assert dataclasses.replace(c, duration_s=0.25, max_ticks=100).tick_limit(1000.0) == 100
    assert dataclasses.replace(c, duration_s=2.0, max_ticks=100).tick_limit(40.0) == 80
    assert dataclasses.replace(c, max_ticks=7).tick_limit(1000.0) == 7


def test_every_live_option_of_the_cli_reaches_the_config():
    """flowtex/cli/live.py builds the config from its arguments: every LiveConfig field is either set there or a
    runtime-only knob (tests and embedding), so a new option cannot be forgotten on one side."""
    cli = (REPO / "flowtex" / "cli" / "live.py").read_text()
    call = cli[cli.index("LiveConfig(dbc"):]
    call = call[:call.index("\n    report = ")]
    runtime_only = {"max_ticks", "drop", "install_signals", "warm"}
    named = set(re.findall(r"(\w+)=", call)) | {"dbc_path", "map_path", "bus"}  # the first three are positional
    assert {f.name for f in dataclasses.fields(LiveConfig)} - runtime_only == named


# --- CanIO's compiled codec --------------------------------------------------------------------------
def _canio_private_names() -> set[str]:
    """Attributes and methods of CanIO whose names start with one underscore (its private state)."""
    tree = ast.parse(CANIO.read_text())
    cls = next(n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "CanIO")
    names = {n.name for n in cls.body if isinstance(n, ast.FunctionDef) and n.name.startswith("_") and not n.name.startswith("__")}
    for node in ast.walk(cls):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self" \
                and isinstance(node.ctx, ast.Store) and node.attr.startswith("_") and not node.attr.startswith("__"):
            names.add(node.attr)
    return names


def _own_private_names(tree: ast.AST) -> set[str]:
    """Private names a file defines itself (``self._x = ...`` or ``def _x``): reading those is its own business."""
    own = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id == "self" \
                and isinstance(node.ctx, ast.Store):
            own.add(node.attr)
        elif isinstance(node, ast.FunctionDef):
            own.add(node.name)
    return own


def test_nothing_outside_canio_reads_canio_private_attributes():
    private = _canio_private_names()
    assert {"_gather", "_gfp", "_warm_up"} <= private  # the walk sees CanIO's private state
    # an attribute is "." then its name, with only blanks, line continuations or a comment between (Python's grammar);
    # parsing only the files whose text has one keeps the walk to a few files instead of every file of three trees
    attribute_text = re.compile(r"\.(?:\s|\\|#[^\n]*)*(?:" + "|".join(map(re.escape, sorted(private))) + r")\b")
    offenders = []
    for root in ("flowtex", "benchmarks", "tests"):
        for path in sorted((REPO / root).rglob("*.py")):
            if path == CANIO:
                continue
            text = path.read_text(encoding="utf-8")
            offenders += [f"{path.relative_to(REPO)}:{text.count(chr(10), 0, m.start()) + 1}: {m.group(0)}"
                          for m in re.finditer(r"\bio\._\w+", text)]
            if not attribute_text.search(text):
                continue  # no ".name" of CanIO's private names in the text, so no such attribute in the tree
            tree = ast.parse(text)
            foreign = private - _own_private_names(tree)
            offenders += [f"{path.relative_to(REPO)}:{n.lineno}: .{n.attr}" for n in ast.walk(tree)
                          if isinstance(n, ast.Attribute) and n.attr in foreign]
    assert offenders == []


def test_the_codec_is_the_canio_own_tables(setup):  # noqa: F811
    """The compiled output call writes through io.codec's arrays: they are CanIO's tables, not copies."""
    g = load_graph(setup / "g.yaml", block_rows=1)
    io = load_io(g, DBC, setup / "m.yaml")
    codec = io.codec
    assert dataclasses.is_dataclass(codec) and codec.arena is g.f and codec.out_ints is not None
    assert io.table_decoder is codec.decoder and io.table_encoder is codec.encoder and io.arena is codec.arena
    with pytest.raises(dataclasses.FrozenInstanceError):
        codec.out_ints = None  # type: ignore[misc]
    assert np.shares_memory(io.out, codec.out_floats) and np.shares_memory(codec.payload, np.frombuffer(codec.encoder.payload, np.uint8))
    g.output_view("vibration")[:] = 0.5
    g.output_view("force")[:] = [1.0, -2.0, 3.0]
    io.guard_and_encode(False)
    assert io.out.tolist() == [0.5, 1.0, -2.0, 3.0]  # map order: vibration, force x/y/z; inside the clamps
    offs = codec.encoder.offsets
    for k, (data, src) in enumerate(codec.fast_frames):
        assert bytes(data) == bytes(src) == bytes(codec.encoder.payload[offs[k]:offs[k + 1]])
        assert data is io.tx[k].data  # the frames the loop sends
    # the Python encoders agree with the compiled bytes (the two codec paths stay equal)
    for enc, msg in zip(io.encoders, io.tx, strict=True):
        expect = bytes(msg.data)
        msg.data[:] = bytes(len(msg.data))
        enc(msg.data)
        assert bytes(msg.data) == expect


def test_table_encoder_rebind_keeps_values():
    enc = TableEncoder([])
    ints = [a.copy() for a in enc.int_tables()]
    enc.rebind(ints, enc.ftab.copy())
    assert enc.int_tables()[0] is ints[0]
    bad = [a.copy() for a in ints]
    bad[0] = bad[0] + 1
    with pytest.raises(ValueError, match="keep its shape, dtype and values"):
        enc.rebind(bad, enc.ftab)


# --- the tick-program protocol ---------------------------------------------------------------------------
def test_the_compiled_graph_is_a_tick_program(setup):  # noqa: F811
    g = load_graph(setup / "g.yaml")
    assert isinstance(g, TickProgram)
    members = [n for n in dir(TickProgram) if not n.startswith("_")] + list(TickProgram.__annotations__)
    for name in members:
        want = inspect.getattr_static(TickProgram, name, None)
        have = inspect.getattr_static(Graph, name, None)
        if callable(want) and not isinstance(want, property):
            assert callable(have), name
            assert list(inspect.signature(have).parameters) == list(inspect.signature(want).parameters), name
        else:
            assert hasattr(g, name), name
    assert isinstance(g.with_block_rows(1), TickProgram)
    assert g.input_view("normal_force").base is g.f and g.output_view("force").base is g.f  # ports are slices of the arena


def test_runtime_takes_tick_programs_not_any():
    """The runtime's functions that drive a graph name the protocol, and no longer probe it with getattr."""
    for name in ("live.py", "tick.py", "fused.py", "canio.py", "preflight.py"):
        text = (REPO / "flowtex" / "runtime" / name).read_text()
        assert "graph: TickProgram" in text, name
        assert not re.search(r"graph: Any\b", text), name
        assert not re.search(r"getattr\(graph\b", text), name


def test_canio_type_is_used_by_the_fused_tick():
    assert "io: CanIO" in (REPO / "flowtex" / "runtime" / "fused.py").read_text()
    assert CanIO.__init__.__annotations__["graph"] == "TickProgram"
