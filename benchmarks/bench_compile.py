"""Compile cost of the fused tier, this tree against a baseline tree, side by side on the same machine.

    python benchmarks/bench_compile.py [--baseline main] [--rounds 3] [--only graphs cold ticks]

The baseline is the git revision ``--baseline`` of this repository, exported to a temporary folder; every figure is
measured in new processes that alternate between the two trees (baseline, this, baseline, this, ...), so a change
of load on a shared machine hits both alike. Sections:

``graphs``
    for every example graph of tests/test_examples.py, with the node kernels already in the cache (each tree has its
    own cache, filled first by a dispatch-tier run of every graph): CPU seconds of the fused tier's compile for an
    offline run (``load_graph`` + ``run``, what a golden test or ``flowtex run --compile fused`` pays), then of a
    following ``step()`` and of ``step_block`` on the one-row layout (what live code compiles).
``cold``
    ``flowtex run graphs/hatt_texture.yaml --compile fused`` with an empty cache (wall and CPU of the process and the
    helpers it waited for), and the same for a structural edit once node kernels are cached (edit -> run on the fused
    tier; also what the background compile after an ``auto`` edit costs).
``ticks``
    the per-tick figures the README quotes, in each tree: the fused texture tick (offline ``run()`` and live
    ``step_block(1)``) and the 10-node chain's ``step()``, each as bench_engine.py measures them, with the ratio to
    the plain-numba floor measured in the same process.

``live``
    ``graphs/live_texture.yaml``'s fused live tick (``fuse_tick`` on the example CAN map), node kernels cached and the
    fused cache empty: CPU seconds until the tick is ready (what the first ``flowtex live`` of a structure compiles
    before its first deadline), then the tick's own time per call (``live_tick`` on the session's arrays, no bus).

``inline``
    in this tree, one process: the texture graph's offline ``run()`` as generated (``block``'s body in ``run``'s loop)
    against the same module with a ``run`` that calls ``block`` (the generator's form before), alternating on the
    same arenas and inputs, outputs compared bit for bit: the per-tick cost of the change without the noise between
    processes.

The CPU figures are ``time.process_time`` (graphs) or the children's ``rusage`` (cold): user + system of every core.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
EXAMPLES = ("accel_preprocess.yaml", "actuator_drive.yaml", "multirate_feedback.yaml", "hatt_texture.yaml",
            "surface_render.yaml", "live_texture.yaml", "live_audio.yaml", "pattern_compliance.yaml",
            "speed_force_texture.yaml")
"""tests/test_examples.py's example graphs (each compiled on the fused tier by its golden test)."""

GRAPH_SCRIPT = """
import json, sys, time
import numpy as np
from flowtex.graph.compiled import load_graph
tier, names = sys.argv[1], sys.argv[2:]
out = {}
for name in names:
    t0 = time.process_time()
    g = load_graph("graphs/" + name, tier=tier)
    g.run({k: np.zeros((64, *s.shape)) for k, s in g.inputs.items()}) if g.inputs else g.run_ticks(64)
    t1 = time.process_time()
    g.reset()
    g.step()
    t2 = time.process_time()
    g.with_block_rows(1).step_block(1)
    t3 = time.process_time()
    out[name] = {"offline": t1 - t0, "step": t2 - t1, "block": t3 - t2}
print(json.dumps(out))
"""

TICKS_SCRIPT = """
import json, sys, tempfile
from pathlib import Path
sys.path.insert(0, "benchmarks")
import bench_engine as be
import flowtex
ticks = int(sys.argv[1])
t = be.bench_tiers(ticks, 3)
with tempfile.TemporaryDirectory() as d:
    path = Path(d) / "chain10.yaml"
    path.write_text(be.chain_yaml())
    s = be.bench_step(flowtex.load_graph(path, tier="fused"), ticks)
print(json.dumps({"fused": t["fused"], "floor": t["floor"], "live_fused": t["live_fused"], "identical": t["identical"],
                  "step_ns": s["step_ns"], "step_floor_ns": s["floor_ns"]}))
"""

INLINE_SCRIPT = """
import json, sys, time
import numpy as np
sys.path.insert(0, "benchmarks")
import bench_texture as bt
from flowtex.graph.codegen import run_source
from flowtex.graph.jit import load_generated
ticks, runs = int(sys.argv[1]), int(sys.argv[2])
ms = bt.cork_like_model_set()
inputs = bt.trajectory(ticks, ms.max_speed, ms.max_force)
g = bt.texture_builder(ms, bt.RATE).build(tier="fused")
plan = g.fused_plan
runs_by = {"inline": g._code.get("run")}
cut = plan.source.index("@njit(cache=True, nogil=True)\\ndef run(")
calling = load_generated(plan.source[:cut] + run_source(), plan.kernels, plan.versions + ";bench-run-calls-block")
calling.run.compile(plan.signatures["run"])
runs_by["call"] = calling.run
out, ns = {}, {"inline": [], "call": []}
for name, fn in runs_by.items():
    g._code._done["run"] = fn  # the Graph's run() then calls this entry point
    out[name] = g.run(inputs)["accel"].copy()
for _ in range(runs):
    for name, fn in runs_by.items():
        g._code._done["run"] = fn
        t0 = time.perf_counter()
        g.run(inputs)
        ns[name].append((time.perf_counter() - t0) / ticks * 1e9)
print(json.dumps({"ns": ns, "identical": bool(np.array_equal(out["inline"].view(np.int64), out["call"].view(np.int64)))}))
"""


LIVE_SCRIPT = """
import json, sys, time
import numpy as np
from flowtex.graph.compiled import load_graph
import flowtex.runtime.live as live
from flowtex.runtime.canio import tick_out
from flowtex.runtime.fused import fuse_tick
dbc, canmap, calls = sys.argv[1], "graphs/devices/example_map.yaml", int(sys.argv[2])
t0 = time.process_time()
g = load_graph("graphs/live_texture.yaml", block_rows=1, tier="fused")
io = live.load_io(g, dbc, canmap)
wd = io.new_watchdog(10**12)
t1 = time.process_time()
fused = fuse_tick(g, io, tick_out, wd.last)
t2 = time.process_time()
g.input_view("normal_force")[:] = 1.5
ns = []
for r in range(5):
    t = time.perf_counter()
    for k in range(calls):
        fused.call(fused.ptrs, 0, k, 0, 10**12, False)
    ns.append((time.perf_counter() - t) / calls * 1e9)
print(json.dumps({"setup": t1 - t0, "tick_compile": t2 - t1, "ns": float(np.median(ns))}))
"""


def export_tree(ref: str, dest: Path) -> str:
    """Export revision ``ref`` of this repository into ``dest``; returns its commit."""
    commit = subprocess.run(["git", "rev-parse", ref], cwd=REPO, capture_output=True, text=True, check=True).stdout.strip()
    archive = subprocess.run(["git", "archive", commit], cwd=REPO, capture_output=True, check=True).stdout
    dest.mkdir(parents=True)
    subprocess.run(["tar", "-x", "-C", str(dest)], input=archive, check=True)
    return commit


def run(tree: Path, cache: Path, argv: list[str]) -> tuple[float, float, str]:
    """Wall seconds, CPU seconds (this child and the children it waited for) and stdout of ``python argv`` in ``tree``."""
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(cache), "FLOWTEX_BACKGROUND": "0", "PYTHONPATH": str(tree)}
    env.pop("NUMBA_CACHE_DIR", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, *argv], cwd=tree, env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SystemExit(f"{tree}: {' '.join(argv[:3])} failed:\n{done.stderr[-2000:]}")
    return wall, after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime, done.stdout


def alternating_json(baseline: str, rounds: int, script: str, warm: bool = False) -> dict[str, list]:
    """``python -c script`` in the baseline revision's tree and in this one, alternating, ``rounds`` times each.

    Each run's stdout is one JSON document; returns {"baseline": [...], "this": [...]}. ``warm``: one unmeasured run
    per tree first (its kernels into that tree's own cache). Prints the baseline's commit and the load average.
    """
    with tempfile.TemporaryDirectory() as tmp:
        work = Path(tmp)
        commit = export_tree(baseline, work / "baseline")
        trees = {"baseline": work / "baseline", "this": REPO}
        print(f"baseline {baseline} = {commit[:12]}; load average {os.getloadavg()[0]:.1f}")
        for label, tree in trees.items() if warm else ():
            run(tree, work / f"cache_{label}", ["-c", script])
        got: dict[str, list] = {label: [] for label in trees}
        for _ in range(rounds):
            for label, tree in trees.items():
                got[label].append(json.loads(run(tree, work / f"cache_{label}", ["-c", script])[2]))
        print(f"load average after {os.getloadavg()[0]:.1f}")
        return got


def renamed(tree: Path, tag: str) -> Path:
    """A copy of graphs/hatt_texture.yaml beside it under a new name: a structure no cache has seen."""
    path = tree / "graphs" / f".bench_compile_{tag}.yaml"
    text = (tree / "graphs" / "hatt_texture.yaml").read_text().replace("name: hatt-texture", f"name: bench-{tag}")
    path.write_text(text)
    return path


def forget_fused_code(cache: Path) -> Path:
    """``cache`` without its generated (fused) modules and their machine code; node kernels and wrappers kept."""
    shutil.rmtree(cache / "codegen", ignore_errors=True)
    for folder in (cache / "numba").glob("*/codegen_*"):  # numba's entries filed by the cache's path (trees before)
        shutil.rmtree(folder)
    for entry in (cache / "numba").glob("*/generated/g_*"):  # filed by the module's digest (flowtex.cache.GENERATED)
        entry.unlink()
    return cache


def section_graphs(trees: dict[str, Path], work: Path, rounds: int) -> dict:
    res: dict = {label: [] for label in trees}
    for label, tree in trees.items():  # node kernels and the dispatch driver into each tree's cache
        run(tree, work / f"cache-{label}", ["-c", GRAPH_SCRIPT, "dispatch", *EXAMPLES])
    for _ in range(rounds):
        for label, tree in trees.items():  # a fresh fused cache each round, the kernels' kept
            cache = forget_fused_code(work / f"cache-{label}")
            res[label].append(json.loads(run(tree, cache, ["-c", GRAPH_SCRIPT, "fused", *EXAMPLES])[2]))
    return {label: {name: {key: float(np.median([r[name][key] for r in rs])) for key in ("offline", "step", "block")}
                    for name in EXAMPLES} for label, rs in res.items()}


def section_cold(trees: dict[str, Path], work: Path, rounds: int) -> dict:
    res: dict = {label: {"cold": [], "edit": []} for label in trees}
    for k in range(rounds):
        for label, tree in trees.items():
            cache = work / f"cold-{label}-{k}"
            cmd = ["-m", "flowtex", "run", "graphs/hatt_texture.yaml", "--input", "graphs/data/exploration.npz",
                   "--output", str(work / f"o-{label}.npz"), "--compile", "fused"]
            res[label]["cold"].append(run(tree, cache, cmd)[:2])
            edit = renamed(tree, f"{label}-{k}")
            try:
                res[label]["edit"].append(run(tree, cache, [*cmd[:3], str(edit.relative_to(tree)), *cmd[4:]])[:2])
            finally:
                edit.unlink()
            shutil.rmtree(cache, ignore_errors=True)
    return {label: {row: [float(np.median([v[j] for v in vs])) for j in (0, 1)] for row, vs in r.items()}
            for label, r in res.items()}


def section_ticks(trees: dict[str, Path], work: Path, rounds: int, ticks: int) -> dict:
    res: dict = {label: [] for label in trees}
    for _ in range(rounds):
        for label, tree in trees.items():
            res[label].append(json.loads(run(tree, work / f"ticks-{label}", ["-c", TICKS_SCRIPT, str(ticks)])[2]))
    return {label: {key: float(np.median([r[key] for r in rs])) if key != "identical" else all(r[key] for r in rs)
                    for key in rs[0]} for label, rs in res.items()}


def section_live(trees: dict[str, Path], work: Path, rounds: int, calls: int) -> dict:
    res: dict = {label: [] for label in trees}
    dbc = str(REPO / "graphs" / "devices" / "example.dbc")
    for label, tree in trees.items():  # node kernels, codecs and the dispatch driver into each tree's cache
        run(tree, work / f"live-{label}", ["-c", GRAPH_SCRIPT, "dispatch", "live_texture.yaml"])
    for _ in range(rounds):
        for label, tree in trees.items():  # a fresh fused cache each round, the kernels' kept
            cache = forget_fused_code(work / f"live-{label}")
            res[label].append(json.loads(run(tree, cache, ["-c", LIVE_SCRIPT, dbc, str(calls)])[2]))
    return {label: {key: float(np.median([r[key] for r in rs])) for key in rs[0]} for label, rs in res.items()}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--baseline", default="main", help="git revision to compare with (default: main)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--ticks", type=int, default=200_000)
    ap.add_argument("--only", nargs="+", choices=("graphs", "cold", "ticks", "live", "inline"),
                    default=("graphs", "cold", "ticks", "live", "inline"))
    args = ap.parse_args()
    work = Path(tempfile.mkdtemp(prefix="flowtex-bench-compile-"))
    try:
        commit = export_tree(args.baseline, work / "baseline")
        trees = {"baseline": work / "baseline", "this": REPO}
        print(f"baseline {args.baseline} = {commit[:12]}; this tree {REPO}; load average {os.getloadavg()[0]:.1f}; "
              f"median of {args.rounds} alternating rounds")
        if "graphs" in args.only:
            g = section_graphs(trees, work, args.rounds)
            print("fused compile CPU s, node kernels cached: offline run / then step() / then step_block (live)")
            for name in EXAMPLES:
                b, t = g["baseline"][name], g["this"][name]
                print(f"  {name:26s} baseline {b['offline']:5.2f} / {b['step']:5.2f} / {b['block']:5.2f}   "
                      f"this {t['offline']:5.2f} / {t['step']:5.2f} / {t['block']:5.2f}   "
                      f"offline {t['offline'] / b['offline']:4.2f} x")
            for key in ("offline", "step", "block"):
                b, t = (sum(g[label][n][key] for n in EXAMPLES) for label in ("baseline", "this"))
                print(f"  total {key:8s} baseline {b:6.1f}  this {t:6.1f}")
        if "cold" in args.only:
            c = section_cold(trees, work, args.rounds)
            print("flowtex run graphs/hatt_texture.yaml --compile fused: wall s / CPU s (helpers included)")
            for row, what in (("cold", "empty cache"), ("edit", "structural edit, kernels cached")):
                b, t = c["baseline"][row], c["this"][row]
                print(f"  {what:32s} baseline {b[0]:6.2f} / {b[1]:6.2f}   this {t[0]:6.2f} / {t[1]:6.2f}   "
                      f"CPU {t[1] / b[1]:4.2f} x")
        if "ticks" in args.only:
            t = section_ticks(trees, work, args.rounds, args.ticks)
            print("per tick (bench_engine.py's measurements, each tree in its own processes)")
            for label, r in t.items():
                print(f"  {label:8s} texture run() {r['fused']:7.1f} ns ({r['fused'] / r['floor']:.2f} x floor)  "
                      f"live step_block(1) {r['live_fused']:7.1f} ns  chain step() {r['step_ns'] / 1000:.3f} us "
                      f"({r['step_ns'] / r['step_floor_ns']:.2f} x floor)  bit-identical tiers {r['identical']}")
            b, n = t["baseline"], t["this"]
            print(f"  this / baseline: texture run() {n['fused'] / b['fused']:.2f}  live {n['live_fused'] / b['live_fused']:.2f}  "
                  f"step() {n['step_ns'] / b['step_ns']:.2f}")
        if "live" in args.only:
            t = section_live(trees, work, args.rounds, args.ticks // 10)
            print("graphs/live_texture.yaml's fused live tick, node kernels cached: CPU s to compile it / ns per call")
            for label, r in t.items():
                print(f"  {label:8s} tick compile {r['tick_compile']:6.2f} s  (graph and CAN map before it {r['setup']:5.2f} s)  "
                      f"{r['ns']:7.1f} ns per tick")
            b, n = t["baseline"], t["this"]
            print(f"  this / baseline: tick compile {n['tick_compile'] / b['tick_compile']:.2f}  per tick {n['ns'] / b['ns']:.2f}")
        if "inline" in args.only:
            r = json.loads(run(REPO, work / "inline", ["-c", INLINE_SCRIPT, str(args.ticks), str(5 * args.rounds)])[2])
            inline, call = (float(np.median(r["ns"][k])) for k in ("inline", "call"))
            pairs = [a / b for a, b in zip(r["ns"]["inline"], r["ns"]["call"], strict=True)]
            print(f"texture run(), one process, {len(pairs)} alternating pairs: block's body in run {inline:.1f} ns/tick, "
                  f"run calling block {call:.1f} ns/tick ({inline / call:.3f} x; pairs {min(pairs):.3f}-{max(pairs):.3f}); "
                  f"bit-identical {r['identical']}")
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    main()
