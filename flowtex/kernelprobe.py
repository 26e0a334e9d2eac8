"""Run one node type's kernel outside any graph and find the mistakes plugin authors make (``flowtex plugin check``).

Each check runs the node as the graph runs it -- ``build`` at representative
port shapes, then ``kernel(p, s, si, inputs..., outputs...)`` on C-contiguous
``(ticks, width)`` float64 arrays -- but on plain numpy arrays, so that what
went wrong can be named:

* **state**: one pass over :data:`TICKS` ticks, the same split into uneven
  blocks, and tick by tick must give identical bits; a kernel that keeps a
  value in a local variable instead of ``s``/``si`` restarts at every block;
* **unwritten outputs**: two one-pass runs whose output buffers start filled
  with two different sentinels; an element that keeps its sentinel was never
  written (the graph would read whatever the buffer held before);
* **finite**: for inputs uniform in [-1, 1], every output value is finite and does not grow without bound
  (:func:`flowtex.dsp.growth.diverging`: a recursion unstable at some parameter value that has not yet reached inf);
* **inputs untouched**: a kernel must not write into its input arrays (another node's outputs);
* **repeatable**: two one-pass runs from the same built state over the same inputs must agree (a kernel drawing
  from numba's global ``np.random`` differs), and so must a third whose output buffers start with another sentinel
  (a kernel reading its output before writing it, ``y[t - 1]`` at ``t = 0``, depends on the buffer's old contents);
* each check runs at the default parameters and again with each numeric parameter at its declared minimum
  (:func:`parameter_sets`: a size of 0, a divisor of 0), where building must succeed or raise ``ParamError``;
* **bounds**: this module is run in a child process with ``NUMBA_BOUNDSCHECK=1``
  (:func:`flowtex.plugincheck.runtime_problems`), so a read or write outside a
  port, ``p``, ``s`` or ``si`` raises ``IndexError`` there instead of corrupting
  memory or crashing the caller.

``python -m flowtex.kernelprobe MODE TARGET TYPE...`` prints the problems as JSON lines
``{"type": TYPE, "line": L, "message": M}`` (``line`` 0: the class's line), see :func:`main`.
"""

from __future__ import annotations

import inspect
import json
import re
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .dsp.growth import diverging
from .errors import FlowtexError, ParamError
from .node_api import REQUIRED, BuildContext, Node, Param, PortSpec
from .node_params import load_files
from .nodecheck import checked_every, checked_latency, checked_outputs, checked_state, error_line

TICKS = 600
"""Ticks of every probe run (enough for a block split and for a slow recursion to blow up)."""
BLOCKS = (1, 7, 64, 1, 200, 13)
"""Uneven block lengths of the chunked run (the rest of :data:`TICKS` follows as one block)."""
SENTINELS = (np.nan, -7.25e306)
"""Output buffer fills of the two unwritten-element runs (a kernel writing either one itself is vanishingly unlikely)."""
RATE_HZ = 1000.0
"""Graph rate the probe builds nodes at (flowtex's usual haptic rate)."""


@dataclass
class Probe:
    """One built instance of a node type: what its kernel receives."""

    label: str
    """The port shapes it was built for, e.g. ``x: scalar``."""
    state: Any
    in_specs: dict[str, PortSpec]
    out_specs: dict[str, PortSpec]


class NoExampleValue(FlowtexError):
    """A required parameter the probe cannot make a value up for (a file, a string): the runtime checks are skipped."""


def example_value(name: str, param: Param) -> Any:
    """A value for a required parameter (inside its bounds), or raise :class:`NoExampleValue` when none can be made up."""
    kind = param.kind
    if kind in ("path", "str"):
        raise NoExampleValue(f"parameter {name!r} ({kind}) is required and has no default; the runtime checks need a value")
    if kind == "bool":
        return False
    if kind == "choice":
        return param.choices[0]
    lo = param.min if param.min is not None else None
    hi = param.max if param.max is not None else None
    if lo is not None and hi is not None:
        value = (lo + hi) / 2
    elif lo is not None:
        value = lo + 1.0
    elif hi is not None:
        value = hi - 1.0
    else:
        value = 1.0
    if kind == "int":
        value = float(round(value))
    if kind == "floats":
        count = param.length[0] if param.length else 1
        return [value] * max(count, 1)
    return value


def parameter_values(cls: type[Node]) -> dict[str, Any]:
    """Validated parameter values: the defaults, and :func:`example_value` for required ones."""
    values = {}
    for name, param in cls.params.items():
        raw = example_value(name, param) if param.default is REQUIRED else param.default
        values[name] = None if raw is None else param.coerce(raw, Path.cwd())
    return values


MAX_LOW_VARIANTS = 6
"""Parameters built at their declared minimum besides the defaults (:func:`parameter_sets`), at most."""
MAX_HIGH_VARIANTS = 6
"""Real-valued parameters built at their declared maximum besides the defaults and minimums, at most."""


def parameter_sets(cls: type[Node]) -> list[tuple[str, dict[str, Any]]]:
    """``("", the defaults)``, then per numeric parameter whose declared minimum is allowed and differs from its default
    ``("name=min", the defaults with that one at its minimum)``: a size or a divisor of 0 is the commonest value a kernel
    or a layout size was not written for (up to :data:`MAX_LOW_VARIANTS` of them). Then per real-valued parameter
    (``float``, ``floats``) ``("name=max", ...)`` at its declared maximum: a filter coefficient computed by a formula
    that holds only for small cutoffs (forward Euler ``a = 2 pi fc / fs``) diverges there (up to
    :data:`MAX_HIGH_VARIANTS`). Integer maximums are not tried: they size buffers and loops, not coefficients."""
    base = parameter_values(cls)
    sets = [("", base)]
    for bound in ("min", "max"):
        most = MAX_LOW_VARIANTS if bound == "min" else MAX_HIGH_VARIANTS
        added = 0
        for name, param in cls.params.items():
            value = getattr(param, bound)
            kinds = ("int", "float", "floats") if bound == "min" else ("float", "floats")
            if param.kind not in kinds or value is None or getattr(param, f"{bound}_exclusive"):
                continue
            count = len(base[name]) if isinstance(base[name], tuple) else (param.length[0] if param.length else 1)
            at = param.coerce([value] * max(count, 1) if param.kind == "floats" else value, Path.cwd())
            if at != base[name] and added < most:
                sets.append((f"{name}={value:g}", {**base, name: at}))
                added += 1
    return sets


def shape_cases(cls: type[Node]) -> list[dict[str, tuple[int, ...]]]:
    """Input shapes to build at: declared shapes as declared; inputs of any shape as a scalar, then as a 3-vector."""
    cases = []
    flexible = [n for n, port in cls.inputs.items() if port.shape is None]
    for any_shape in ([(), (3,)] if flexible else [()]):
        shapes: dict[str, tuple[int, ...]] = {}
        for name, port in cls.inputs.items():
            shape = port.shape
            if shape is None:
                shapes[name] = any_shape
            elif isinstance(shape, str):
                shapes[name] = shapes.get(shape[1:], any_shape)
            else:
                shapes[name] = tuple(shape)
        cases.append(shapes)
    return cases


def build_probes(cls: type[Node]) -> tuple[list[Probe], list[tuple[int, str]]]:
    """Build ``cls`` at each of :func:`shape_cases` for each of :func:`parameter_sets`, and the problems of building it.

    At the defaults, a failure raises (FlowtexError / the plugin's own exception). At a parameter's bound, a
    FlowtexError (the node refuses the value with a message: well done) skips that set, and any other exception is a
    problem: the graph would accept the value and then fail with the plugin's traceback.
    """
    probes: list[Probe] = []
    problems: list[tuple[int, str]] = []
    for at, values in parameter_sets(cls):
        try:
            probes += _probes_at(cls, at, values)
        except FlowtexError:
            if not at:
                raise
        except Exception as exc:
            if not at:
                raise
            problems.append((error_line(exc, inspect.getsourcefile(cls) or ""), f"building the node with {at}, a bound "
                             f"its declaration allows, raised {type(exc).__name__}: {exc}; raise ParamError for a value the "
                             "node cannot take, or declare a bound it can"))
    return probes, problems


def _probes_at(cls: type[Node], at: str, values: dict[str, Any]) -> list[Probe]:
    """``cls`` built at each of :func:`shape_cases` with the parameter ``values`` (``at`` names the non-default one)."""
    params, files = load_files(cls, values)  # files read into objects, as the resolver does
    probes = []
    for shapes in shape_cases(cls):
        in_specs = {}
        for name, port in cls.inputs.items():
            unit = port.unit if port.unit not in ("*",) and not port.unit.startswith("=") else ""
            in_specs[name] = PortSpec(shapes[name], unit)
        checked_every(cls, "probe", cls.own_every(dict(params), RATE_HZ, dict.fromkeys(cls.inputs, 1)))
        node = cls("probe", dict(params), BuildContext(rate=RATE_HZ, base_dir=Path.cwd(), files=files))
        checked_latency(cls, "probe", node.latency_samples())
        out_specs = checked_outputs(cls, "probe", node.resolve(in_specs))
        state = checked_state(cls, "probe", node.build(in_specs, out_specs), cls.build)
        label = ", ".join(f"{n}: {PortSpec(s).describe().split(' [')[0]}" for n, s in shapes.items()) or "no inputs"
        probes.append(Probe(label + (f"; {at}" if at else ""), state, in_specs, out_specs))
    return probes


def _arrays(probe: Probe) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    st = probe.state
    return (np.array(st.params, dtype=np.float64).ravel(), np.array(st.state, dtype=np.float64).ravel(),
            np.array(st.istate, dtype=np.int64).ravel())


def run_blocks(cls: type[Node], probe: Probe, inputs: list[np.ndarray], blocks: list[int], fill: float) -> list[np.ndarray]:
    """Outputs of the kernel run from the built state over ``inputs`` split into ``blocks`` (ticks per call)."""
    kernel = cls.get_kernel()
    p, s, si = _arrays(probe)
    outs = [np.full((TICKS, spec.width), fill) for spec in probe.out_specs.values()]
    start = 0
    for n in blocks:
        stop = start + n
        kernel(p, s, si, *[x[start:stop] for x in inputs], *[y[start:stop] for y in outs])
        start = stop
    return outs


def _split() -> list[int]:
    blocks = list(BLOCKS)
    return blocks + [TICKS - sum(blocks)]


def probe_problems(cls: type[Node]) -> list[tuple[int, str]]:
    """Every runtime problem of ``cls`` as (line in the kernel's file or 0, message), checked at each shape case."""
    source = inspect.getsourcefile(getattr(cls.get_kernel(), "py_func", cls)) or ""
    rng = np.random.default_rng(12345)
    probes, problems = build_probes(cls)
    for probe in probes:
        problems += _problems_at(cls, probe, rng, source)
    seen: set[tuple[int, str]] = set()
    unique = []
    for line, message in problems:  # a mistake found at the defaults is said once, not again at each minimum
        key = (line, re.sub(r" \(built with [^)]*\)", "", message))
        if key not in seen:
            seen.add(key)
            unique.append((line, message))
    return unique


def _problems_at(cls: type[Node], probe: Probe, rng: np.random.Generator, source: str) -> list[tuple[int, str]]:
    """The runtime problems of one built instance (see :func:`probe_problems`)."""
    problems: list[tuple[int, str]] = []
    inputs = [rng.uniform(-1.0, 1.0, (TICKS, spec.width)) for spec in probe.in_specs.values()]
    names = list(probe.out_specs)
    at = f" (built with {probe.label})"
    try:
        given = [x.copy() for x in inputs]
        one = run_blocks(cls, probe, given, [TICKS], SENTINELS[0])
        written = [n for n, x, y in zip(probe.in_specs, inputs, given, strict=True) if not np.array_equal(x, y, equal_nan=True)]
        if written:
            problems.append((0, f"kernel writes into its input {written[0]!r}{at}; an input is another node's output "
                                "buffer, which other nodes read too: write only the outputs, s and si"))
            return problems
        other = run_blocks(cls, probe, inputs, [TICKS], SENTINELS[1])
        again = run_blocks(cls, probe, inputs, [TICKS], SENTINELS[0])
        chunked = run_blocks(cls, probe, inputs, _split(), SENTINELS[0])
        ticked = run_blocks(cls, probe, inputs, [1] * TICKS, SENTINELS[0])
    except IndexError as exc:
        problems.append((error_line(exc, source), f"kernel reads or writes outside its arrays{at}: IndexError: {exc}; index "
                         "only rows < x.shape[0] of each port, columns < its width, and within p, s and si as build() sized them"))
        return problems
    except Exception as exc:
        problems.append((error_line(exc, source), f"kernel raised {type(exc).__name__}: {exc}{at}"))
        return problems
    unrepeatable = set()
    for name, a, b, a_again in zip(names, one, other, again, strict=True):
        stuck = np.isnan(a) & (b == SENTINELS[1])  # kept the sentinel of each run: never written
        if stuck.any():
            cols = sorted({int(c) for c in np.nonzero(stuck)[1]})
            problems.append((0, f"output {name!r}: element(s) {cols} of {a.shape[1]} per tick never written{at}; write "
                                "every element of every row (the graph reads whatever the buffer held before)"))
        random = ~_same(a, a_again)  # one fill, one state, one input
        reads = ~stuck & ~_same(a, b)  # two fills: written values that depend on what the buffer held
        for mask, message in ((random, UNREPEATABLE), (reads, READS_OUTPUT)):
            if mask.any():
                unrepeatable.add(name)
                problems.append((0, message.format(name=name, tick=_first(mask), at=at)))
                break
    for k, name in enumerate(names):  # one line per output: the chunked run, else the tick-by-tick one
        if name in unrepeatable:
            continue
        for label, runs in (("chunked (blocks of " + ", ".join(map(str, BLOCKS)) + ", ...)", chunked), ("tick-by-tick", ticked)):
            differ = ~_same(one[k], runs[k])
            if differ.any():
                problems.append((0, f"output {name!r}: {label} and one-pass runs differ from tick {_first(differ)}{at}; keep every "
                                    "value that lives from one call to the next in s or si (live runs call the kernel tick by tick)"))
                break
    for name, a in zip(names, other, strict=True):  # filled with a finite sentinel: only written values can be non-finite
        bad = ~np.isfinite(a)
        if bad.any():
            problems.append((0, f"output {name!r} is not finite from tick {_first(bad)} for inputs uniform in [-1, 1]{at} "
                                f"(value {a[bad][0]!r})"))
        elif (growth := diverging(a)) is not None:
            problems.append((0, f"output {name!r} grows without bound for inputs uniform in [-1, 1]{at}: {growth}; "
                                "a recursion whose pole left the unit circle (check the coefficient's formula at these "
                                "parameters, or declare a bound where it holds)"))
    return problems


UNREPEATABLE = ("output {name!r}: two runs from the same built state over the same inputs differ from tick {tick}{at}; "
                "the kernel draws numbers kept outside s and si (numba's np.random, a global), so no run can be repeated "
                "or a session replayed: set uses_seed = True and draw from seed_state()'s generator in si (flowtex.dsp.rng)")
"""The problem of an output that differs between two identical runs (``name``, first ``tick``, ``at``: built with)."""
READS_OUTPUT = ("output {name!r} depends on what its buffer held before the call, from tick {tick}{at}; the kernel reads "
                "{name!r} before writing it (y[t - 1] at t = 0 reads the block's last row, left from another call or "
                "another node): keep values from earlier ticks in s")
"""The problem of an output that differs only with the buffer's prior fill."""


def _same(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Elementwise: equal values, or NaN in both."""
    return (a == b) | (np.isnan(a) & np.isnan(b))


def _first(mask: np.ndarray) -> int:
    """The first tick (row) where ``mask`` holds."""
    return int(np.nonzero(mask.any(axis=1))[0][0])


ALLOCATORS = re.compile(r"call [^@\n]*@(NRT_MemInfo_alloc\w*|NRT_MemInfo_new\w*|NRT_Allocate\w*|NRT_MemInfo_varsize_alloc\w*)")
"""numba runtime functions that allocate heap memory (np.empty, array expressions, slices copied, lists ...)."""


def allocations(cls: type[Node]) -> list[str]:
    """Allocator calls in the kernel's LLVM IR (its Python wrapper excluded), compiled for the graph's argument types.

    Valid only when nothing was loaded from numba's disk cache (run with an empty ``NUMBA_CACHE_DIR``).
    """
    from .nodecheck import check_kernel_compiles

    check_kernel_compiles(cls)
    kernel = cls.get_kernel()
    found: set[str] = set()
    for sig in kernel.signatures:
        for block in re.split(r"\n(?=define )", kernel.inspect_llvm(sig)):
            head = block.split("(", 1)[0]
            if block.startswith("define") and "@cpython." not in head and "@cfunc." not in head:
                found.update(ALLOCATORS.findall(block))
    return sorted(found)


def _probe_type(mode: str, cls: type[Node]) -> list[dict]:
    """One node type's JSON items for ``mode`` (``allocations`` or ``runtime``)."""
    if mode == "allocations":
        return [{"allocations": allocations(cls)}]
    found: list[tuple[int, str]]
    try:
        found = probe_problems(cls)
    except (NoExampleValue, ParamError) as exc:  # no value to build with, or the node refuses the probe's shapes: a note
        found = [(0, f"note: {exc}")]
    except FlowtexError as exc:  # resolve(), build(), own_every() or latency_samples() broke the contract: a problem, and
        return [{"line": 0, "message": str(exc), "located": True}]  # its message names the plugin's file and line
    except Exception as exc:  # __init__, resolve() or build() raised: the plugin's error, at its line
        found = [(error_line(exc, inspect.getsourcefile(cls) or ""), f"building the node raised {type(exc).__name__}: {exc}")]
    return [{"line": line, "message": message} for line, message in found]


def main(argv: list[str]) -> int:
    """Child-process entry: ``allocations|runtime TARGET TYPE...`` -> JSON lines on stdout.

    Every node type is framed by ``{"start": TYPE}`` and ``{"done": TYPE}`` (each line flushed), so that the parent
    names the type that crashed or hung this process and checks the ones after it in a new one; one process checks
    every type of a plugin file (its imports and numba's start-up cost about a second each time).
    """
    from .plugincheck import node_types

    mode, target, *type_names = argv
    classes = node_types(target)
    for type_name in type_names:
        print(json.dumps({"start": type_name}), flush=True)
        for item in _probe_type(mode, classes[type_name]):
            print(json.dumps({"type": type_name, **item}), flush=True)
        print(json.dumps({"done": type_name}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
