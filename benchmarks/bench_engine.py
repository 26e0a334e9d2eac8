"""Graph engine benchmark: offline throughput, per-tick step cost, start-up time, both compile tiers.

    python benchmarks/bench_engine.py [--samples 1000000] [--runs 5] [--ticks 200000] [--only SECTION ...]

Sections: ``chain`` (10-node chain vs scipy, step() per tier, start-up),
``tiers`` (texture graph ns/tick, fused vs dispatch vs plain numba), ``edit``
(the edit-run loop of docs/engine.md in new processes: cold first run,
unchanged warm run, structural edits; ``--cold`` includes an empty-cache run).

Every speed is measured side by side with its baseline in this process and
reported as a ratio, with the numerical error the configuration buys.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import textwrap
import time
from pathlib import Path

import numpy as np
from numba import njit
from scipy import signal

import flowtex
from flowtex.compile.service import background_running

RATE = 10_000.0
CUTOFFS = [3000, 2800, 2600, 2400, 2200, 2000, 1800, 1600, 1400, 1200]  # Hz, one 2nd-order lowpass each
REPO = Path(__file__).resolve().parents[1]


def chain_yaml() -> str:
    nodes = "\n".join(f"  s{k}: {{type: butterworth, params: {{kind: lowpass, order: 2, cutoff_hz: {c}}}}}" for k, c in enumerate(CUTOFFS))
    edges = "\n".join(["  - x -> s0.x"] + [f"  - s{k - 1}.y -> s{k}.x" for k in range(1, len(CUTOFFS))])
    return f"flowtex: 1\nname: chain10\nrate: {RATE}\ninputs:\n  x: {{}}\nnodes:\n{nodes}\nedges:\n{edges}\noutputs:\n  y: s{len(CUTOFFS) - 1}.y\n"


def chain_sos() -> np.ndarray:
    return np.vstack([signal.butter(2, c, fs=RATE, output="sos") for c in CUTOFFS])


@njit(cache=True)
def fused_tick(sos: np.ndarray, z: np.ndarray, x: float) -> float:
    """The floor: one hand-written numba function doing the 10 sections for one sample."""
    for k in range(sos.shape[0]):
        y = sos[k, 0] * x + z[k, 0]
        z[k, 0] = sos[k, 1] * x - sos[k, 4] * y + z[k, 1]
        z[k, 1] = sos[k, 2] * x - sos[k, 5] * y
        x = y
    return x


def bench_offline(graph: flowtex.Graph, samples: int, runs: int) -> dict:
    x = np.random.default_rng(0).standard_normal(samples)
    sos = chain_sos()
    graph.run({"x": x[:1000]})
    signal.sosfilt(sos, x[:1000])
    ours, ref_t, ratios = [], [], []
    for _ in range(runs):  # paired: both on the same data, back to back
        t0 = time.perf_counter()
        y = graph.run({"x": x})["y"]
        t1 = time.perf_counter()
        ref = signal.sosfilt(sos, x)
        t2 = time.perf_counter()
        ours.append(t1 - t0)
        ref_t.append(t2 - t1)
        ratios.append((t1 - t0) / (t2 - t1))
    err = float(np.max(np.abs(y - ref)) / np.max(np.abs(ref)))
    return {"flowtex_ms": 1e3 * np.median(ours), "sosfilt_ms": 1e3 * np.median(ref_t),
            "ratio": float(np.median(ratios)), "ns_per_sample": 1e9 * np.median(ours) / samples, "rel_err": err}


def bench_step(graph: flowtex.Graph, ticks: int) -> dict:
    x = np.random.default_rng(1).standard_normal(ticks)
    sos = chain_sos()
    z = np.zeros((sos.shape[0], 2))
    fused_tick(sos, z, 0.0)
    graph.reset()
    step = graph.step
    values = [{"x": float(v)} for v in x]
    floor_ns, step_ns = [], []
    out_step = np.empty(ticks)
    out_floor = np.empty(ticks)
    per = 1000
    for start in range(0, ticks, per):  # interleave chunks so both see the same machine state
        t0 = time.perf_counter_ns()
        for k in range(start, start + per):
            out_step[k] = step(values[k])["y"]
        t1 = time.perf_counter_ns()
        for k in range(start, start + per):
            out_floor[k] = fused_tick(sos, z, values[k]["x"])
        t2 = time.perf_counter_ns()
        step_ns.append((t1 - t0) / per)
        floor_ns.append((t2 - t1) / per)
    err = float(np.max(np.abs(out_step - out_floor)) / np.max(np.abs(out_floor)))
    s, f = float(np.median(step_ns)), float(np.median(floor_ns))
    return {"step_ns": s, "floor_ns": f, "ratio": s / f, "rel_err_vs_floor": err}


def bench_startup(graph_path: Path, input_path: Path) -> dict:
    env = dict(os.environ)
    tmp = Path(tempfile.mkdtemp(prefix="flowtex-bench-"))
    env["FLOWTEX_CACHE_DIR"] = str(tmp / "flowtex")
    env["NUMBA_CACHE_DIR"] = str(tmp / "numba")
    cmd = [sys.executable, "-m", "flowtex", "run", str(graph_path), "--input", str(input_path), "--output", str(tmp / "out.npz")]
    times = []
    for _ in range(3):
        t0 = time.perf_counter()
        subprocess.run(cmd, check=True, env=env, capture_output=True)
        times.append(time.perf_counter() - t0)
    shutil.rmtree(tmp, ignore_errors=True)
    return {"cold_s": times[0], "warm_s": min(times[1:])}


def bench_warm_build(tmpdir: Path) -> dict:
    """Build a graph, then one that differs only in parameter values: the second reuses compiled code."""
    base = chain_yaml()
    a, b = tmpdir / "a.yaml", tmpdir / "b.yaml"
    a.write_text(base)
    b.write_text(base.replace("cutoff_hz: 3000", "cutoff_hz: 2900"))
    flowtex.load_graph(a)
    t0 = time.perf_counter()
    flowtex.load_graph(b)
    return {"warm_build_s": time.perf_counter() - t0}


def bench_tiers(ticks: int, runs: int) -> dict:
    """Texture graph (bench_texture.py's lookup every tick + synthesis) on both tiers beside the plain numba floor.

    Offline run() and the live path (step_block(1) per tick), the three timed alternately in this process.
    """
    sys.path.insert(0, str(REPO / "benchmarks"))
    import bench_texture as bt

    ms = bt.cork_like_model_set()
    inputs = bt.trajectory(ticks, ms.max_speed, ms.max_force)
    out: dict = {"fused": [], "dispatch": [], "floor": [], "live_fused": [], "live_dispatch": []}
    # the texture graph bench_texture.py times (flowtex.fit.texture_graph.texture_builder), built in memory
    graphs = {t: bt.texture_builder(ms, bt.RATE).build(tier=t) for t in ("fused", "dispatch")}
    live = {t: g.with_block_rows(1) for t, g in graphs.items()}
    y = {t: g.run(inputs)["accel"].copy() for t, g in graphs.items()}
    bt.run_floor(ms, {k: v[:100] for k, v in inputs.items()})
    for _ in range(runs):
        for t, g in graphs.items():
            t0 = time.perf_counter()
            g.run(inputs)
            out[t].append((time.perf_counter() - t0) / ticks * 1e9)
        out["floor"].append(bt.run_floor(ms, inputs))
        for t, g in live.items():
            out["live_" + t].append(bt.live_ns(g, inputs, min(ticks, 50_000), 1))
    # a feedback loop and a node every 4 ticks: tick-by-tick execution, where the dispatch tier pays per tick
    path = REPO / "graphs" / "multirate_feedback.yaml"
    data = np.load(REPO / "graphs" / "data" / "accel_demo.npz")
    loop = {t: flowtex.load_graph(path, tier=t) for t in ("fused", "dispatch")}
    rec = {k: np.tile(data[k], (max(1, ticks // data[k].shape[0]),) + (1,) * (data[k].ndim - 1)) for k in loop["fused"].inputs}
    n = next(iter(rec.values())).shape[0]
    for g in loop.values():
        g.run(rec)  # warm
    for _ in range(runs):
        for t, g in loop.items():
            t0 = time.perf_counter()
            g.run(rec)
            out.setdefault("loop_" + t, []).append((time.perf_counter() - t0) / n * 1e9)
    med = {k: float(np.median(v)) for k, v in out.items()}
    med["identical"] = bool(np.array_equal(y["fused"].view(np.int64), y["dispatch"].view(np.int64)))
    return med


def _timed(cmd: list[str], env: dict) -> tuple[float, str]:
    t0 = time.perf_counter()
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, done.stdout.strip().rsplit("(", 1)[-1].rstrip(")")


def _wait_background(cache: Path) -> float:
    """Seconds until the background fused compile (docs/engine.md) of this cache has finished."""
    t0 = time.perf_counter()
    while background_running(cache):
        time.sleep(0.2)
    return time.perf_counter() - t0


def edited(text: str, k: int) -> str:
    """The texture graph with ``k`` extra gain nodes, each with an output (a structural edit; node types seen before)."""
    nodes = "".join(f"  extra{j}: {{type: gain, params: {{k: {j + 2}.0}}}}\n" for j in range(k))
    edges = "".join(f"  - {'mute' if j == 0 else f'extra{j - 1}'}.y -> extra{j}.x\n" for j in range(k))
    outs = "".join(f"  extra{j}: extra{j}.y\n" for j in range(k))
    text = text.replace("\nedges:\n", "\n" + nodes + "edges:\n" + edges, 1)
    return text.replace("\noutputs:\n", "\noutputs:\n" + outs, 1)


def bench_edit(cold: bool) -> dict:
    """The README's first command and structural edits of its graph, each a new process (wall time, process start included).

    One cache for the whole section. ``auto`` tier throughout, as ``flowtex run`` defaults to.
    """
    graph = REPO / "graphs" / "hatt_texture.yaml"
    rec = REPO / "graphs" / "data" / "exploration.npz"
    tmp = Path(tempfile.mkdtemp(prefix="flowtex-edit-"))
    env = {**os.environ, "FLOWTEX_CACHE_DIR": str(tmp / "cache") if cold else os.environ.get("FLOWTEX_CACHE_DIR", "")}
    env = {k: v for k, v in env.items() if v}
    env.pop("FLOWTEX_BACKGROUND", None)
    cache = Path(env.get("FLOWTEX_CACHE_DIR", Path.home() / ".cache" / "flowtex"))

    def run(path: Path, *extra: str) -> tuple[float, str]:
        return _timed([sys.executable, "-m", "flowtex", "run", str(path), "--input", str(rec), "--output", str(tmp / "o.npz"),
                       *extra], env)

    res: dict = {}
    if cold:
        res["cold"] = run(graph)
    else:
        run(graph)  # node types (and maybe the fused tick) cached
    res["background_s"] = _wait_background(cache)
    res["warm"] = min(run(graph), run(graph))
    text = graph.read_text()
    stamp = f"{time.time_ns()}"  # a structure this cache has never seen: rename the graph
    for k in (1, 2, 3):
        path = graph.parent / f".bench_edit_{stamp}_{k}.yaml"  # beside the original: its relative model paths hold
        path.write_text(edited(text, k).replace("name: hatt-texture", f"name: edit-{stamp}-{k}"))
        try:
            res[f"edit{k}"] = run(path)  # the earlier edit's background compile is still running for k > 1
        finally:
            path.unlink()
    res["warm_during_background"] = run(graph)
    _wait_background(cache)
    path = graph.parent / f".bench_edit_{stamp}_fused.yaml"
    path.write_text(edited(text, 4).replace("name: hatt-texture", f"name: edit-{stamp}-f"))
    try:
        res["edit_fused"] = run(path, "--compile", "fused")  # today's behaviour: every edit compiles the fused tick
    finally:
        path.unlink()
    shutil.rmtree(tmp, ignore_errors=True)
    return res


def report_tiers(t: dict) -> str:
    return textwrap.dedent(f"""    texture graph (bench_texture.py: lookup every tick -> arma_synth, AR 19/MA 17), median of paired runs
      fused run()            {t['fused']:8.1f} ns/tick   {t['fused'] / t['floor']:5.2f} x floor  (target <= 1500 ns, <= 2.5 x floor)
      dispatch run()         {t['dispatch']:8.1f} ns/tick   {t['dispatch'] / t['fused']:5.2f} x fused  (target <= 2 x fused)
      plain numba floor      {t['floor']:8.1f} ns/tick
      live step_block(1)     fused {t['live_fused']:7.1f}  dispatch {t['live_dispatch']:7.1f} ns/tick  ({t['live_dispatch'] / t['live_fused']:.2f} x)
      outputs bit-identical  {t['identical']}
    graphs/multirate_feedback.yaml (feedback loop, a node every 4 ticks: tick-by-tick execution), offline run()
      fused {t['loop_fused']:7.1f}  dispatch {t['loop_dispatch']:7.1f} ns/tick  ({t['loop_dispatch'] / t['loop_fused']:.2f} x)""")


def report_edit(e: dict) -> str:
    warm = e["warm"][0]
    lines = ["edit-run loop: 'flowtex run graphs/hatt_texture.yaml' (auto tier), new process each, wall time"]
    if "cold" in e:
        lines.append(f"  cold first run (empty cache)     {e['cold'][0]:6.2f} s  {e['cold'][1]}  (target <= 10 s)")
    lines.append(f"  unchanged, warm                  {warm:6.2f} s  {e['warm'][1]}")
    for k in (1, 2, 3):
        d, tier = e[f"edit{k}"]
        lines.append(f"  edit {k}: +{k} gain node(s) + output(s) {d:6.2f} s  {tier}  {d / warm:5.2f} x warm (target <= 2.5 x)")
    lines.append(f"  unchanged, background running    {e['warm_during_background'][0]:6.2f} s  {e['warm_during_background'][1]}")
    lines.append(f"  edit, --compile fused (old way)  {e['edit_fused'][0]:6.2f} s  {e['edit_fused'][0] / warm:5.2f} x warm")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=1_000_000)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--ticks", type=int, default=200_000)
    ap.add_argument("--only", nargs="+", choices=("chain", "tiers", "edit"), default=("chain", "tiers", "edit"))
    ap.add_argument("--cold", action="store_true", help="edit section: start from an empty cache (compiles everything)")
    args = ap.parse_args()
    if "tiers" in args.only:
        print(report_tiers(bench_tiers(args.ticks, args.runs)))
    if "edit" in args.only:
        print(report_edit(bench_edit(args.cold)))
    if "chain" not in args.only:
        return
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "chain10.yaml"
        path.write_text(chain_yaml())
        graph = flowtex.load_graph(path)
        off = bench_offline(graph, args.samples, args.runs)
        step = bench_step(graph, args.ticks)
        dstep = bench_step(flowtex.load_graph(path, tier="dispatch"), args.ticks)
        warm = bench_warm_build(Path(d))
    start = bench_startup(REPO / "graphs" / "accel_preprocess.yaml", REPO / "graphs" / "data" / "accel_demo.npz")
    print(textwrap.dedent(f"""\
    10 cascaded 2nd-order Butterworth sections as 10 nodes, {args.samples:,} samples, median of {args.runs} paired runs
      flowtex run()         {off['flowtex_ms']:8.2f} ms  ({off['ns_per_sample']:.2f} ns/sample)
      scipy sosfilt         {off['sosfilt_ms']:8.2f} ms
      ratio flowtex/scipy   {off['ratio']:8.3f}   (target <= 1.0)   max rel. error vs sosfilt {off['rel_err']:.1e}
    per-tick step() from Python (mapping in, mapping out), median over {args.ticks:,} ticks
      flowtex step()        {step['step_ns'] / 1000:8.3f} us
      fused numba floor     {step['floor_ns'] / 1000:8.3f} us
      ratio step/floor      {step['ratio']:8.2f}   (target <= 3, and <= 3 us)   max rel. error vs floor {step['rel_err_vs_floor']:.1e}
      dispatch tier step()  {dstep['step_ns'] / 1000:8.3f} us  ({dstep['ratio']:.2f} x its floor run)
    start-up of 'flowtex run graphs/accel_preprocess.yaml' (wall time, new process)
      cold (empty caches)   {start['cold_s']:8.2f} s
      warm                  {start['warm_s']:8.2f} s    (target < 2 s)
    second graph differing only in parameters, same process
      warm build            {warm['warm_build_s']:8.3f} s    (target <= 0.5 s)"""))


if __name__ == "__main__":
    main()
