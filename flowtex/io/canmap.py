"""Map files: which DBC signals feed which graph inputs, which graph outputs drive which signals.

The format is documented in docs/live.md. In short::

    flowtex_map: 1
    overrun_limit_ms: 2          # optional: a tick this late forces safe values
    inputs:
      position:                  # graph input (shape [3])
        signals: [ToolPosition.PosX, ToolPosition.PosY, ToolPosition.PosZ]
        scale: 0.001             # graph value = DBC physical value * scale + offset
        offset: 0.0
        timeout_ms: 10           # required: older than this -> watchdog -> safe outputs
    outputs:
      vibration:                 # graph output (scalar)
        signal: VoiceCoilCmd.Current
        scale: 1.0               # DBC physical value = graph value * scale + offset
        clamp: [-1.5, 1.5]       # required, in graph units
        safe: 0.0                # optional (default 0), in graph units, inside clamp; the DBC must carry it
        peak: {limit: 2.0, max_ms: 20}   # optional: |value| up to limit for max_ms, refilled over recover_ms
    audio: {rate: 8000, block: 64, channels: [{output: vibration, scale: 1.5, clip: 1.0}]}   # optional: flowtex.io.audiomap

:func:`load_map` checks the file against the DBC and (when given) the graph's
input/output shapes and raises :class:`~flowtex.errors.GraphError` whose lines
read ``map.yaml:LINE:COL: problem (fix)``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from cantools.database.can import Database

from ..errors import DataError, Diagnostic, GraphError, Location
from ..limits import excerpt
from ..node_decl import PortSpec
from ..schema import core as schema
from ..schema.core import INVALID, Collector, check_unknown, value_of
from ..schema.devmap import DEFAULT_OVERRUN_MS, INPUT_BINDING, MAP, OUTPUT_BINDING, PEAK, PEAK_RECOVER_RATIO, PER_COMPONENT
from ..yamlsource import LocDict, LocList, load_yaml, read_source
from .audiomap import AudioMap, parse_audio
from .dbc import find_signal, suggest
from .dbcrange import check_value, sendable_range
from .mapsafety import GuardBounds, check_clamps, check_frame_lengths, check_transmitters, check_unbound_signals
from .mapunits import check_binding_units

__all__ = ["DEFAULT_OVERRUN_MS", "CanMap", "InputBinding", "OutputBinding", "load_map", "map_for_ports"]


@dataclass
class Binding:
    """One graph input or output bound to ``width`` DBC signals (C order over the port's shape)."""

    name: str
    width: int
    signals: list[tuple[str, str]]
    """``(message name, signal name)`` per component."""
    scale: np.ndarray
    offset: np.ndarray
    loc: Location


@dataclass
class InputBinding(Binding):
    timeout_ms: float = 0.0


@dataclass
class OutputBinding(Binding):
    lo: np.ndarray = field(default_factory=lambda: np.zeros(0))
    hi: np.ndarray = field(default_factory=lambda: np.zeros(0))
    safe: np.ndarray = field(default_factory=lambda: np.zeros(0))
    peak_limit: np.ndarray | None = None
    peak_ms: float = 0.0
    recover_ms: float = 0.0
    """Time within the clamp that refills an empty peak allowance (``peak: recover_ms``, default
    :data:`~flowtex.schema.devmap.PEAK_RECOVER_RATIO` x ``peak_ms``); 0 without ``peak``."""
    guard: GuardBounds | None = None
    """What the output guard clamps to: ``lo``/``hi`` (the map's clamp) and the peak range with each bound the DBC
    would send beyond them moved inward onto its grid (:func:`~flowtex.io.mapsafety.check_clamps`); set by
    :func:`load_map`, the only bounds the runtime guards with."""


@dataclass
class CanMap:
    """A checked map file."""

    path: Path
    inputs: dict[str, InputBinding]
    outputs: dict[str, OutputBinding]
    overrun_limit_ms: float = DEFAULT_OVERRUN_MS
    audio: AudioMap | None = None
    """The ``audio`` section (:mod:`flowtex.io.audiomap`), if the map has one."""
    warnings: list[str] = field(default_factory=list)
    """``map.yaml:LINE:COL: ...`` per pass-through binding whose DBC unit differs from its graph port's by no known factor
    (:func:`~flowtex.io.mapunits.check_binding_units`); shown by ``flowtex validate`` and before a live session."""

    def sensor_messages(self) -> list[str]:
        """Messages read by the runtime, in order of first use."""
        return list(dict.fromkeys(m for b in self.inputs.values() for m, _ in b.signals))

    def actuator_messages(self) -> list[str]:
        """Messages sent by the runtime every tick, in order of first use (the send order)."""
        return list(dict.fromkeys(m for b in self.outputs.values() for m, _ in b.signals))


_number = schema.is_number


def load_map(path: str | Path, db: Database, dbc_path: str | Path = "DBC",
             graph_inputs: dict[str, int] | None = None, graph_outputs: dict[str, int] | None = None,
             input_units: Mapping[str, str] | None = None, output_units: Mapping[str, str] | None = None) -> CanMap:
    """Read and check the map file ``path`` against ``db`` and the graph.

    ``graph_inputs``/``graph_outputs`` map port names to widths (number of
    scalars); None skips the graph checks (the stand-alone device simulator).
    Every graph input must be bound; graph outputs may stay unbound (not sent).
    ``input_units``/``output_units`` (port name -> unit) check each pass-through binding's DBC unit
    (:func:`~flowtex.io.mapunits.check_binding_units`); None skips that check.
    """
    path = Path(path)
    data = load_yaml(read_source(path, "map file"), str(path))
    p = Collector(str(path))
    if not isinstance(data, LocDict):
        raise GraphError([Diagnostic(Location(str(path), 1, 1), "a map file is a mapping with keys 'inputs' and 'outputs'")])
    check_unknown(p, data, MAP)
    value_of(p, data, MAP, "flowtex_map")
    overrun = value_of(p, data, MAP, "overrun_limit_ms")
    overrun = DEFAULT_OVERRUN_MS if overrun is INVALID else overrun
    used: dict[tuple[str, str], str] = {}
    inputs: dict[str, InputBinding] = {}
    outputs: dict[str, OutputBinding] = {}
    for section, keys, known, dest in (("inputs", INPUT_BINDING, graph_inputs, inputs), ("outputs", OUTPUT_BINDING, graph_outputs, outputs)):
        raw = data.get(section)
        if raw is None:
            p.add(data.pos if section not in data.key_pos else data.key_pos[section], MAP.keys[section].missing)
            continue
        if not isinstance(raw, LocDict):
            p.add(data.value_pos.get(section), MAP.keys[section].message)
            continue
        for name, entry in raw.items():
            pos = raw.key_pos[name]
            if known is not None and name not in known:
                p.add(pos, f"the graph has no {section[:-1]} {name!r}{suggest(str(name), list(known))}")
                continue
            if not isinstance(entry, LocDict):
                p.add(raw.value_pos[name], f"{section[:-1]} {name!r}: expected a mapping with 'signal' or 'signals'")
                continue
            b = _binding(p, db, dbc_path, section, str(name), entry, pos, known[name] if known is not None else None, keys, used)
            if b is not None:
                dest[str(name)] = b
    if graph_inputs is not None and isinstance(data.get("inputs"), LocDict):
        for name in graph_inputs:
            if name not in data["inputs"]:
                p.add(data.key_pos["inputs"], f"graph input {name!r} is not bound: add '{name}: {{signal: MESSAGE.SIGNAL, timeout_ms: N}}'")
    sensor = {m for b in inputs.values() for m, _ in b.signals}
    for b in outputs.values():
        both = sorted({m for m, _ in b.signals} & sensor)
        if both:
            p.add((b.loc.line, b.loc.column), f"output {b.name!r} writes message {both[0]!r}, which inputs also read; "
                  "a message is either sensor or actuator")
    _one_message_per_id(p, db, [*inputs.values(), *outputs.values()])
    check_transmitters(db, list(inputs.values()), list(outputs.values()), p.add)
    check_frame_lengths(db, list(outputs.values()), p.add)
    check_unbound_signals(db, list(outputs.values()), p.add)
    check_clamps(db, list(outputs.values()), p.add)
    audio = parse_audio(data["audio"], data.value_pos["audio"], p, graph_outputs) if "audio" in data else None
    warnings = check_binding_units(db, list(inputs.values()), list(outputs.values()), input_units or {}, output_units or {},
                                   p.add) if input_units is not None or output_units is not None else []
    p.raise_if_any()
    return CanMap(path, inputs, outputs, float(overrun), audio, warnings)


def map_for_ports(path: str | Path, db: Database, dbc_path: str | Path, inputs: Mapping[str, PortSpec],
                  outputs: Mapping[str, PortSpec]) -> CanMap:
    """:func:`load_map` against a graph's ports (``inputs``/``outputs``: name -> PortSpec): names, widths, and the DBC
    unit of every pass-through binding against its port's unit (:func:`~flowtex.io.mapunits.check_binding_units`).
    What ``flowtex live``, replay and ``flowtex validate GRAPH --map`` load, so they see the same errors and warnings."""
    return load_map(path, db, dbc_path, {n: s.width for n, s in inputs.items()}, {n: s.width for n, s in outputs.items()},
                    {n: s.unit for n, s in inputs.items()}, {n: s.unit for n, s in outputs.items()})


def _one_message_per_id(p: Collector, db: Database, bindings: list[Binding]) -> None:
    """Two bound messages with one ID number are refused: the runtime, the simulated device and cantools look
    received frames up by ID number, so a standard and an extended frame with one number would be confused."""
    owner: dict[int, str] = {}
    for b in bindings:
        for m in dict.fromkeys(m for m, _ in b.signals):
            fid = int(db.get_message_by_name(m).frame_id)
            if owner.setdefault(fid, m) != m:
                p.add((b.loc.line, b.loc.column), f"{b.name!r} binds message {m!r}, whose CAN ID {fid:#x} is also that of message "
                      f"{owner[fid]!r} bound in this map; give the two messages different IDs in the DBC")


def _per_component(p: Collector, entry: LocDict, key: str, width: int, default: float, what: str) -> np.ndarray | None:
    v = entry.get(key, default)
    pos = entry.value_pos.get(key)
    if _number(v):
        return np.full(width, float(v))
    if isinstance(v, LocList) and len(v) == width and all(_number(x) for x in v):
        return np.array([float(x) for x in v])
    p.add(pos, PER_COMPONENT.message.format(what=what, key=key, width=width, got=excerpt(v)))
    return None


def _binding(p: Collector, db: Database, dbc_path: str | Path, section: str, name: str, entry: LocDict,
             pos: tuple[int, int], width: int | None, keys: schema.Record, used: dict) -> Binding | None:
    what = f"{section[:-1]} {name!r}"
    ok = check_unknown(p, entry, keys, what=what)
    if ("signal" in entry) == ("signals" in entry):
        p.add(pos, f"{what}: give exactly one of 'signal: MESSAGE.SIGNAL' or 'signals: [MESSAGE.SIGNAL, ...]'")
        return None
    key = "signal" if "signal" in entry else "signals"
    names = entry[key]
    names_pos = [entry.value_pos[key]] if key == "signal" else list(getattr(names, "item_pos", []))
    if key == "signal":
        names = [names]
    if not isinstance(names, list) or not names or not all(isinstance(n, str) for n in names):
        p.add(entry.value_pos[key], f"{what}: '{key}' must name DBC signals as MESSAGE.SIGNAL strings")
        return None
    if width is not None and len(names) != width:
        p.add(entry.value_pos[key], f"{what} has {width} component(s) but {len(names)} signal(s) are listed; list one signal per component")
        return None
    width = len(names)
    signals: list[tuple[str, str]] = []
    for n, npos in zip(names, names_pos or [entry.value_pos[key]] * len(names), strict=False):
        try:
            msg, sig = find_signal(db, n, dbc_path)
        except DataError as exc:
            p.add(npos, str(exc).replace(f"{dbc_path}: ", "", 1) + f" in {dbc_path}")
            ok = False
            continue
        if msg.is_multiplexed():
            p.add(npos, f"message {msg.name!r} is multiplexed; flowtex maps only plain messages")
            ok = False
            continue
        k = (msg.name, sig.name)
        if k in used:
            p.add(npos, f"signal {msg.name}.{sig.name} is already bound to {used[k]}; bind each signal once")
            ok = False
            continue
        used[k] = what
        signals.append(k)
    scale = _per_component(p, entry, "scale", width, 1.0, what)
    offset = _per_component(p, entry, "offset", width, 0.0, what)
    if scale is not None and np.any(scale == 0):
        p.add(entry.value_pos.get("scale"), f"{what}: scale must not be 0")
        ok = False
    if not ok or scale is None or offset is None:
        return None
    loc = Location(p.path, *pos)
    if section == "inputs":
        if entry.get("timeout_ms") is None:
            p.add(pos, INPUT_BINDING.keys["timeout_ms"].missing.format(what=what))
            return None
        t = value_of(p, entry, INPUT_BINDING, "timeout_ms", what=what)
        if t is INVALID:
            return None
        return InputBinding(name, width, signals, scale, offset, loc, timeout_ms=float(t))
    safe = _per_component(p, entry, "safe", width, 0.0, what)
    if safe is None or not _safe_sendable(p, db, entry, signals, safe, scale, offset, what):
        return None
    return _output(p, entry, name, width, signals, scale, offset, safe, loc, what)


def _safe_sendable(p: Collector, db: Database, entry: LocDict, signals: list[tuple[str, str]], safe: np.ndarray,
                   scale: np.ndarray, offset: np.ndarray, what: str) -> bool:
    """Every safe value must arrive as itself within half an LSB under the DBC (checked before the clamps): else the
    encoder's DBC clamp or saturation would send another value on every safe frame and at exit."""
    for j, (m, s) in enumerate(signals):
        msg = db.get_message_by_name(m)
        sig = msg.get_signal_by_name(s)
        physical = float(safe[j] * scale[j] + offset[j])
        got = check_value(msg, sig, physical)
        if got is None:
            continue
        lo, hi = sendable_range(sig)
        unit = f" {sig.unit}" if sig.unit else ""
        via = "" if (scale[j], offset[j]) == (1.0, 0.0) else f" (DBC value {physical:g}{unit} after the map's scale and offset)"
        glo, ghi = sorted(((lo - offset[j]) / scale[j], (hi - offset[j]) / scale[j]))
        graph = "" if not via else f", i.e. [{glo:g}, {ghi:g}] in graph units"
        p.add(entry.value_pos.get("safe", entry.value_pos.get("signal", entry.value_pos.get("signals"))),
              f"{what}: safe value {safe[j]:g}{via} cannot be sent in {m}.{s}: it would arrive as {got:g}{unit}; "
              f"the DBC range of {m}.{s} is [{lo:g}, {hi:g}]{unit}{graph}; choose a safe value inside it or fix the DBC")
        return False
    return True


def _output(p: Collector, entry: LocDict, name: str, width: int, signals, scale, offset, safe: np.ndarray, loc: Location,
            what: str) -> OutputBinding | None:
    clamp = entry.get("clamp")
    cpos = entry.value_pos.get("clamp")
    if clamp is None:
        p.add(loc, OUTPUT_BINDING.keys["clamp"].missing.format(what=what))
        return None
    lo = hi = None
    if isinstance(clamp, LocList) and len(clamp) == 2 and all(_number(x) for x in clamp):
        lo, hi = np.full(width, float(clamp[0])), np.full(width, float(clamp[1]))
    elif isinstance(clamp, LocList) and len(clamp) == width and all(
            isinstance(c, LocList) and len(c) == 2 and all(_number(x) for x in c) for c in clamp):
        lo, hi = np.array([float(c[0]) for c in clamp]), np.array([float(c[1]) for c in clamp])
    if lo is None:
        p.add(cpos, f"{what}: clamp must be [LOW, HIGH] or one [LOW, HIGH] per component ({width}), got {clamp!r}")
        return None
    if np.any(lo > hi):
        p.add(cpos, f"{what}: clamp LOW must not exceed HIGH, got {clamp!r}")
        return None
    if np.any(safe < lo) or np.any(safe > hi):
        p.add(entry.value_pos.get("safe", cpos), f"{what}: safe value {safe.tolist()} lies outside clamp {clamp!r}; "
              "choose a safe value inside the clamp range")
        return None
    peak_limit, peak_ms, recover_ms = None, 0.0, 0.0
    if "peak" in entry:
        peak = entry["peak"]
        ppos = entry.value_pos["peak"]
        if not isinstance(peak, LocDict) or not set(PEAK.required) <= set(peak) <= set(PEAK.keys):
            p.add(ppos, OUTPUT_BINDING.keys["peak"].message.format(what=what))
            return None
        dur = value_of(p, peak, PEAK, "max_ms", what=what)
        rec = value_of(p, peak, PEAK, "recover_ms", what=what) if "recover_ms" in peak else None
        if dur is INVALID or rec is INVALID:
            return None
        limit = _per_component(p, peak, "limit", width, 0.0, what + " peak")
        if limit is None:
            return None
        if np.any(limit < hi):
            p.add(peak.value_pos["limit"], f"{what}: peak limit {limit.tolist()} must be at least the clamp HIGH {hi.tolist()}")
            return None
        peak_limit, peak_ms = limit, float(dur)
        recover_ms = PEAK_RECOVER_RATIO * peak_ms if rec is None else float(rec)
    return OutputBinding(name, width, signals, scale, offset, loc, lo=lo, hi=hi, safe=safe, peak_limit=peak_limit, peak_ms=peak_ms,
                         recover_ms=recover_ms)
