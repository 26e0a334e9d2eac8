"""Knob sweeps: every combination of knob values on the same input and seed; ns/tick and error against a reference.

A knob is ``node.param=v1,v2,...`` (any node parameter, values read as YAML),
``node.every=1,2,4`` (the node's rate divider), or, for a scene file, a
planner knob (``plan=planned,all``, ``plan.COMPONENT=auto,keep,drop``:
flowtex.bench.scenes). Timing: every
configuration is compiled first, then all are run round-robin ``repeats``
times in this process (side by side, so machine load hits all alike) and the
median ns/tick is reported.
"""

from __future__ import annotations

import itertools
import math
import tempfile
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.errors import pareto_front, signal_error
from ..errors import FlowtexError
from ..io.recordings import Recording
from ..limits import MAX_CONFIGURATIONS
from ..runtime.offline import check_recording_fits
from ..yamlsource import parse_value
from .scenes import PLAN_KNOB, check_plan_knob, is_plan_knob, is_scene_file, write_planned_graph

VIBRATION_UNITS = ("m/s^2",)


@dataclass
class Config:
    values: dict[str, Any]
    ns_per_tick: float = float("nan")
    errors: dict[str, float] = field(default_factory=dict)
    pareto: bool = False
    timed_on: str = "local"


def check_configuration_count(sizes: Mapping[str, int]) -> None:
    """Refuse a sweep of more than :data:`~flowtex.limits.MAX_CONFIGURATIONS` configurations: the product of the
    knobs' numbers of values (``sizes``: knob -> count), named one by one."""
    count = math.prod(sizes.values())
    if count > MAX_CONFIGURATIONS:
        listed = " x ".join(f"{n} ({k})" for k, n in sizes.items())
        raise FlowtexError(f"--knob: {listed} = {count:,} configurations; bench runs at most {MAX_CONFIGURATIONS} "
                           "(docs/bench.md): give fewer values")


def parse_knob(text: str) -> tuple[str, list[Any]]:
    """``"lookup.every=1,2"`` -> ``("lookup.every", [1, 2])`` (values parsed as YAML scalars)."""

    key, sep, values = text.partition("=")
    node, dot, param = key.strip().partition(".")
    if not sep or not values.strip() or not (key.strip() == PLAN_KNOB or (dot and node and param)):
        raise FlowtexError(f"--knob {text}: expected NODE.PARAM=V1,V2,... (e.g. synth.every=1,2,4)")
    if values.strip().startswith("["):  # a list-valued param: semicolon-separated lists, e.g. lookup.order=[6,4];[4,2]
        parts = values.split(";")
    else:
        parts = values.split(",")
    check_configuration_count({key.strip(): len(parts)})  # before parsing each value: a knob this long can never run
    parsed = [parse_value(v, f"--knob {key.strip()}") for v in parts]
    if is_plan_knob(key.strip()):
        check_plan_knob(key.strip(), parsed)
    return key.strip(), parsed


def build(graph_path: str | Path, values: dict[str, Any], plugins: tuple[str | Path, ...] = (), tier: str = "dispatch"):
    """Compile the graph with ``values`` applied (``node.every`` sets the rate divider, others are params).

    A scene file is planned first, with the ``plan`` knobs applied (flowtex.bench.scenes).
    """
    plan = {k: v for k, v in values.items() if is_plan_knob(k)}
    if is_scene_file(graph_path):
        with tempfile.TemporaryDirectory(prefix="flowtex-bench-") as tmp:
            graph_file = write_planned_graph(graph_path, plan, Path(tmp) / "scene_graph.yaml", plugins)
            return _build_graph(graph_file, {k: v for k, v in values.items() if k not in plan}, plugins, tier)
    if plan:
        raise FlowtexError(f"--knob {next(iter(plan))}: plan knobs need a scene file, and {graph_path} is a graph")
    return _build_graph(graph_path, values, plugins, tier)


def _build_graph(graph_path: str | Path, values: dict[str, Any], plugins: tuple[str | Path, ...], tier: str):
    from ..graph.compiled import Graph

    return Graph(resolve_config(graph_path, values, plugins), tier=tier)


def resolve_config(graph_path: str | Path, values: dict[str, Any], plugins: tuple[str | Path, ...]):
    """The checked (not compiled) graph file ``graph_path`` with the node knobs of ``values`` applied (``node.every``
    sets the rate divider, others are params); plan knobs are the caller's (:func:`build`)."""
    from ..graph.resolve import resolve_graph
    from ..graph.spec import load_spec
    from ..registry import load_registry

    params = {k: v for k, v in values.items() if not k.endswith(".every")}
    spec = load_spec(graph_path, params)
    for key, v in values.items():
        if key.endswith(".every"):
            node = key.rsplit(".", 1)[0]
            if node not in spec.nodes:
                raise FlowtexError(f"--knob {key}: no node {node!r} in {graph_path}")
            if isinstance(v, bool) or not isinstance(v, int) or v < 1:
                raise FlowtexError(f"--knob {key}: every must be a positive integer, got {v!r}")
            spec.nodes[node].every = v
    return resolve_graph(spec, load_registry(plugins))


def graph_inputs(graph: Any, inputs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The recording's signals that ``graph`` reads (a recording may carry more, e.g. for another configuration of a scene)."""
    return {name: inputs[name] for name in graph.inputs if name in inputs}


def default_metric(unit: str) -> str:
    """LSD for vibrations (m/s^2), RMS for everything else (forces, positions)."""
    return "lsd" if unit in VIBRATION_UNITS else "rms"


def combinations(knobs: dict[str, list[Any]]) -> list[dict[str, Any]]:
    """Every combination of the knobs' values (knob -> value), in the sweep's order."""
    names = list(knobs)
    return [dict(zip(names, vals, strict=True)) for vals in itertools.product(*(knobs[n] for n in names))]


def reference_values(knobs: dict[str, list[Any]], reference: dict[str, Any] | None) -> dict[str, Any]:
    """The reference configuration: the first value of every knob, then ``reference`` (``--reference``)."""
    return {**{n: v[0] for n, v in knobs.items()}, **(reference or {})}


def sweep(graph_path: str | Path, inputs: dict[str, np.ndarray] | Recording, knobs: dict[str, list[Any]], reference: dict[str, Any] | None = None,
          outputs: list[str] | None = None, metric: str | None = None, repeats: int = 5, seed: int | None = None,
          plugins: tuple[str | Path, ...] = (), client: Any = None, tier: str = "dispatch") -> tuple[list[Config], list[str]]:
    """Run every combination of ``knobs``; returns the configurations (with ns/tick, errors, Pareto flag) and the outputs compared.

    ``inputs``: the signals, or the :class:`~flowtex.io.recordings.Recording` they come from, which is then checked
    against the reference configuration's graph as ``flowtex run`` checks it (its stated rate, its inputs, the units
    it states: :func:`flowtex.runtime.offline.check_recording_fits`) before anything runs.
    The reference is ``reference`` (default: the first value of every knob).
    The Pareto front is over (ns/tick, error of the first compared output).
    With a Dask ``client`` each configuration is compiled, run and timed on a
    worker (timings labelled "dask workers": not comparable to local ones).
    ``tier``: how each configuration is compiled (docs/engine.md). The default,
    ``dispatch``, compiles nothing for knobs that change the graph's shape
    (``every``, ``plan``) once the node types are cached; ``fused`` compiles each
    shape (seconds each) for the fastest ticks.
    """
    combos = combinations(knobs)
    ref_values = reference_values(knobs, reference)
    ref_graph = build(graph_path, ref_values, plugins, tier)
    if isinstance(inputs, Recording):
        check_recording_fits(inputs, ref_graph.name, ref_graph.rate, ref_graph.inputs, inputs.path or "the recording")
        inputs = dict(inputs.arrays)
    if outputs is None:
        outputs = list(ref_graph.outputs)
    missing = [o for o in outputs if o not in ref_graph.outputs]
    if missing:
        raise FlowtexError(f"--outputs: the graph has no output {', '.join(missing)}; it has {', '.join(ref_graph.outputs)}")
    ref_out = ref_graph.run(graph_inputs(ref_graph, inputs), seed=seed)
    configs = [Config(c) for c in combos]
    if client is not None:
        futures = client.map(run_config, [str(Path(graph_path).resolve())] * len(combos), combos, [inputs] * len(combos), [outputs] * len(combos),
                             [seed] * len(combos), [repeats] * len(combos), [plugins] * len(combos), [tier] * len(combos),
                             pure=False)
        results = client.gather(futures)
        timed_on = f"dask workers, {tier} tier"
    else:
        results = _run_local(graph_path, combos, inputs, outputs, seed, repeats, plugins, tier)
        timed_on = f"local, {tier} tier"
    for cfg, (out, ns) in zip(configs, results, strict=True):
        cfg.ns_per_tick = ns
        cfg.timed_on = timed_on
        for name in outputs:
            m = metric or default_metric(ref_graph.outputs[name].unit)
            # a planned scene without a component has no output for it: it renders zeros there
            got = out[name] if name in out else np.zeros_like(ref_out[name])
            cfg.errors[name] = signal_error(m, ref_out[name], got, ref_graph.rate)
    mark_pareto(configs, outputs[0])
    return configs, outputs


def _time_runs(graphs: list, inputs: dict[str, np.ndarray], seed: int | None, repeats: int) -> list[float]:
    """Median ns/tick of each graph, the graphs run round-robin ``repeats`` times (side by side)."""
    ticks = next(iter(inputs.values())).shape[0]
    times: list[list[float]] = [[] for _ in graphs]
    for _ in range(repeats):
        for k, g in enumerate(graphs):
            g.reset(seed)
            own = graph_inputs(g, inputs)
            t0 = time.perf_counter_ns()
            g.process(own)
            times[k].append((time.perf_counter_ns() - t0) / ticks)
    return [float(np.median(t)) for t in times]


def _run_local(graph_path, combos, inputs, outputs, seed, repeats, plugins, tier) -> list[tuple[dict[str, np.ndarray], float]]:
    graphs = [build(graph_path, c, plugins, tier) for c in combos]
    outs = []
    for g in graphs:
        result = g.run(graph_inputs(g, inputs), seed=seed)
        outs.append({name: result[name] for name in outputs if name in result})
    return list(zip(outs, _time_runs(graphs, inputs, seed, repeats), strict=True))


def run_config(graph_path, values, inputs, outputs, seed, repeats, plugins, tier="dispatch") -> tuple[dict[str, np.ndarray], float]:
    """One configuration, compiled, run and timed where this is called (a Dask worker): (outputs, median ns/tick)."""
    g = build(graph_path, values, plugins, tier)
    result = g.run(graph_inputs(g, inputs), seed=seed)
    return {name: result[name] for name in outputs if name in result}, _time_runs([g], inputs, seed, repeats)[0]


def mark_pareto(configs: list[Config], output: str) -> None:
    """Flag the configurations on the (ns/tick, error of ``output``) Pareto front."""
    front = pareto_front(np.array([c.ns_per_tick for c in configs]), np.array([c.errors[output] for c in configs]))
    for c, f in zip(configs, front, strict=True):
        c.pareto = bool(f)


def table(configs: list[Config], outputs: list[str], metrics: dict[str, str]) -> list[list[str]]:
    """Rows (header first) of the result table: knob values, ns/tick, one error column per output, Pareto mark."""
    knobs = list(configs[0].values) if configs else []
    timed = configs[0].timed_on if configs else "local"
    head = knobs + [f"ns/tick ({timed})"] + [f"{o} {metrics[o]}" for o in outputs] + ["pareto"]
    rows = [head]
    for c in configs:
        rows.append([str(c.values[k]) for k in knobs] + [f"{c.ns_per_tick:.0f}"] + [f"{c.errors[o]:.4g}" for o in outputs]
                    + ["*" if c.pareto else ""])
    return rows


def format_table(rows: list[list[str]]) -> str:
    widths = [max(len(r[i]) for r in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.rjust(w) for cell, w in zip(r, widths, strict=True)) for r in rows)
