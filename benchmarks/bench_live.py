"""Live loop at the graph's rate against the in-process simulated device, with and without --rt.

    python benchmarks/bench_live.py [SECONDS=60]

Graph: graphs/live_texture.yaml with graphs/data/exploration.npz if both exist,
else a small stand-in (position -> lowpass -> gain -> force, normal force -> gain
-> vibration) and a synthetic 3 s recording; the report says which ran.
Reports lateness p50/p99/p99.9/max, ticks later than 1 ms, compute p99, the share
of ticks whose actuator frames were sent before the next deadline, and the
sensor-to-actuator latency (device publish -> actuator frame, in ticks).
Targets with --rt: lateness p99 <= 50 us, < 0.1 % ticks late > 1 ms, compute p99 <= 20 us.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from flowtex.graph.compiled import load_graph
from flowtex.runtime.live import run_live

REPO = Path(__file__).resolve().parents[1]
STAND_IN = """flowtex: 1
name: stand_in
rate: 1000
inputs:
  position: {shape: [3], unit: mm}
  normal_force: {unit: N}
nodes:
  lp: {type: first_order_lowpass, params: {cutoff_hz: 50}}
  k: {type: gain, params: {k: 0.01}}
  v: {type: gain, params: {k: 0.25}}
edges: [position -> lp.x, lp.y -> k.x, normal_force -> v.x]
outputs: {force: k.y, vibration: v.y}
"""


def main(seconds: float = 60.0) -> None:
    tmp = Path(tempfile.mkdtemp(prefix="flowtex-bench-live-"))
    graph_path, rec = REPO / "graphs" / "live_texture.yaml", REPO / "graphs" / "data" / "exploration.npz"
    if not (graph_path.exists() and rec.exists()):
        graph_path, rec = tmp / "stand_in.yaml", tmp / "rec.npz"
        graph_path.write_text(STAND_IN)
        t = np.arange(3000) / 1000.0
        np.savez(rec, position=np.stack([100 * np.sin(2 * np.pi * t), 50 * np.cos(6 * np.pi * t), 10 + 0 * t], axis=1),
                 normal_force=3 + np.sin(10 * np.pi * t), rate=np.float64(1000))
    print(f"graph {graph_path.name}, recording {rec.name}, {seconds:g} s per run")
    for rt in (False, True):
        g = load_graph(graph_path)
        r = run_live(g, REPO / "graphs/devices/example.dbc", REPO / "graphs/devices/example_map.yaml", simulate=rec,
                     duration_s=seconds, rt=rt, status=None)
        s = r.summary
        lat, comp = s["lateness_us"], s["compute_us"]
        period_ns = 1e9 / g.rate
        within = float(np.mean(r.send_offset_ns < period_ns)) * 100 if r.ticks else 0.0
        dev = r.device
        lat_ticks = dev.latency_s[:min(dev.latency_count, dev.latency_s.size)] * g.rate
        print(f"--rt {'on ' if rt else 'off'} ({r.rt_message or 'no rt requested'})")
        print(f"  ticks {s['ticks']} missed {s['missed']} late>1ms {s['late_over_1ms']} ({100 * s['late_over_1ms'] / max(1, s['ticks']):.3f} %)"
              f" watchdog {s['watchdog_events']}")
        print(f"  lateness us: p50 {lat['p50']:.1f} p99 {lat['p99']:.1f} p99.9 {lat['p999']:.1f} max {lat['max']:.1f}")
        print(f"  compute us:  p50 {comp['p50']:.1f} p99 {comp['p99']:.1f} max {comp['max']:.1f}")
        print(f"  actuator frames sent within their own tick: {within:.3f} % of ticks")
        if lat_ticks.size:
            print(f"  sensor->actuator latency (device publish -> actuator frame): p50 {np.percentile(lat_ticks, 50):.3f} "
                  f"p99 {np.percentile(lat_ticks, 99):.3f} max {lat_ticks.max():.3f} ticks")


if __name__ == "__main__":
    main(float(sys.argv[1]) if len(sys.argv) > 1 else 60.0)
