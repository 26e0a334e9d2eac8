"""Cost saved by the scene planner: ns/tick of the planned graph against the same scene with every component on.

Six of 002's study surfaces (synthetic stand-ins, flowtex.datasets.study),
speed 50-250 mm/s, force 0.5-2.5 N; the graphs run side by side in this
process on graphs/data/exploration.npz with the active surface cycling every
2 s. Prints the median ns/tick of each, their ratio, the components kept, and the
error the planned graph has against all components on (force RMS, vibration LSD).
The same comparison from the command line: ``flowtex bench SCENE --knob plan=planned,all``.

    PYTHONPATH=. python3 benchmarks/bench_scene.py [--repeats 7]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from flowtex.datasets.study import write_study_scene
from flowtex.dsp.errors import signal_error
from flowtex.graph.compiled import load_graph
from flowtex.scene.build import plan_to_graph

REPO = Path(__file__).resolve().parents[1]
SURFACES = ("EPDM_Foam", "Whiteboard", "MDF", "Silk_1", "Brick_1", "Carpet_3")


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--repeats", type=int, default=7)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        scene = write_study_scene(folder, SURFACES)
        all_on = folder / "all_on.yaml"
        all_on.write_text(scene.read_text().replace("surfaces:", "thresholds: {texture: 0, friction: 0, taps: 0}\nsurfaces:"))
        plans = {"planned": plan_to_graph(scene, folder / "planned_graph.yaml"),
                 "all on": plan_to_graph(all_on, folder / "all_on_graph.yaml")}
        graphs = {"planned": load_graph(folder / "planned_graph.yaml"), "all on": load_graph(folder / "all_on_graph.yaml")}
    rec = dict(np.load(REPO / "graphs/data/exploration.npz"))
    n = rec["normal_force"].shape[0]
    inputs = {k: rec[k] for k in ("position", "normal_force", "normal")}
    inputs["surface"] = (np.arange(n) // 2000 % len(SURFACES)).astype(np.float64)
    times: dict[str, list[float]] = {k: [] for k in graphs}
    for _ in range(args.repeats):
        for name, g in graphs.items():
            g.reset()
            t0 = time.perf_counter_ns()
            g.process(inputs)
            times[name].append((time.perf_counter_ns() - t0) / n)
    med = {k: float(np.median(v)) for k, v in times.items()}
    for name in graphs:
        kept = sum(d.keep for s in plans[name].values() for d in s.decisions.values())
        total = sum(len(s.decisions) for s in plans[name].values())
        print(f"{name:8s} {med[name]:8.0f} ns/tick  ({len(graphs[name].resolved.nodes)} nodes, {kept}/{total} components)")
    print(f"planned / all on: {med['planned'] / med['all on']:.2f}  (saves {med['all on'] - med['planned']:.0f} ns/tick)")
    # the error the planner buys, against all components on (same input and seed)
    outs = {name: g.run(inputs) for name, g in graphs.items()}
    for name, metric in (("force", "rms"), ("vibration", "lsd")):
        if name in outs["planned"] and name in outs["all on"]:
            err = signal_error(metric, outs["all on"][name], outs["planned"][name], 1000.0)
            unit = "dB" if metric == "lsd" else graphs["planned"].outputs[name].unit
            print(f"planned vs all on: {name} {metric} {err:.4g} {unit}")


if __name__ == "__main__":
    main()
