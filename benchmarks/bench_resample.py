"""The resample node in a compiled graph vs scipy.signal.upfirdn with the same filter, in ns per output sample.

    python benchmarks/bench_resample.py [--samples 400000] [--runs 3]

Down-sampling 1 kHz -> 250 Hz (D = 4) and up-sampling 250 Hz -> 1 kHz (U = 4,
from a node with every: 4) at 60 and 80 dB, side by side in one process on the
same data; the largest difference from upfirdn is printed (it must be <= 1e-12
relative to the output's peak: the same sums in another order).
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np
from scipy import signal

import flowtex
from flowtex.dsp.resample_stream import polyphase_filter

DOWN = """\
flowtex: 1
name: bench-down
rate: 1000
inputs:
  x: {}
nodes:
  rs: {type: resample, params: {to_hz: 250}}
edges:
  - x -> rs.x
outputs:
  y: rs.y
"""

UP = """\
flowtex: 1
name: bench-up
rate: 1000
inputs:
  x: {}
nodes:
  slow: {type: gain, every: 4, params: {k: 1.0}}
  rs: {type: resample, params: {to_hz: 1000}}
edges:
  - x -> slow.x
  - slow.y -> rs.x
outputs:
  y: rs.y
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=400_000, help="ticks of the graph (1 kHz)")
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    n = args.samples
    x = np.random.default_rng(0).standard_normal(n)
    print(f"{n} ticks at 1 kHz; median of {args.runs} paired runs; ns per output sample")
    print(f"{'case':<22} {'taps':>5} {'latency':>8} {'graph ns':>9} {'upfirdn ns':>11} {'ratio':>6} {'max rel diff':>13}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, text, up, down in (("down 1000->250 Hz", DOWN, 1, 4), ("up 250->1000 Hz", UP, 4, 1)):
            path = Path(tmp) / f"{name.split()[0]}.yaml"
            path.write_text(text)
            for atten in (60.0, 80.0):
                g = flowtex.load_graph(path, {"rs.atten_db": atten})
                h = polyphase_filter(up, down, atten)
                g.run({"x": x[:1000]})
                xin = x[::4] if up > 1 else x
                n_out = n // 4 if down > 1 else n
                ours, ref_t = [], []
                for _ in range(args.runs):
                    t0 = time.perf_counter()
                    y = g.run({"x": x})["y"]
                    t1 = time.perf_counter()
                    ref = signal.upfirdn(up * h, xin, up, down)
                    t2 = time.perf_counter()
                    ours.append(t1 - t0)
                    ref_t.append(t2 - t1)
                got = y[::4] if down > 1 else y
                diff = float(np.max(np.abs(got - ref[:got.size])) / np.max(np.abs(ref[:got.size])))
                ns_g = 1e9 * np.median(ours) / n_out
                ns_r = 1e9 * np.median(ref_t) / n_out
                lat = g.resolved.nodes["rs"].node.latency_samples()
                print(f"{name + f' {atten:g} dB':<22} {h.size:>5} {lat:>5} ms {ns_g:>9.0f} {ns_r:>11.0f} {ns_g / ns_r:>6.2f} {diff:>13.1e}")


if __name__ == "__main__":
    main()
