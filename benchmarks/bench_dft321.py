"""Streaming DFT321 cost per tick: the dft321 node in a compiled graph vs a plain numpy STFT/ISTFT of the same frames.

    python benchmarks/bench_dft321.py [--samples 200000] [--runs 3]

For frames 32, 64 and 128 (Hann, hop = frame/2) it times, side by side in
this process on the same data:

* ``graph``:     the ``dft321`` node in a compiled flowtex graph (in-place radix-2 FFT, no allocation);
* ``graph+pc``:  the same with the power correction on (the node's default);
* ``dft``:       the node with method: dft (direct O(frame^2) DFT);
* ``rocket``:    the same overlap-add loop in numba, but with rocket-fft's np.fft.rfft/irfft per hop
                 (allocates two arrays per hop): is the direct DFT the right choice at these frames?
* ``numpy``:     the baseline, a vectorised numpy STFT -> combine -> ISTFT over the whole recording.

It prints ns per tick, the ratio to the numpy baseline and the largest
difference from the baseline's output (relative to the output's peak).
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
import time
from pathlib import Path

import numpy as np
from numba import njit

import flowtex
from flowtex.dsp.dft321_stream import windows

GRAPH = """\
flowtex: 1
name: bench-dft321
rate: 1000
inputs:
  acc: {shape: [3], unit: m/s^2}
nodes:
  red: {type: dft321}
edges:
  - acc -> red.x
outputs:
  y: red.y
"""


def numpy_stft(x: np.ndarray, frame: int, hop: int, wa: np.ndarray, ws: np.ndarray) -> np.ndarray:
    """Offline STFT/ISTFT DFT321 on the node's frames (ending at ticks e with (e+1) % hop == 0), aligned like the node."""
    n = x.shape[0]
    xp = np.concatenate([np.zeros((frame - 1, 3)), x])  # zeros before the start, as the node assumes
    frames = np.lib.stride_tricks.sliding_window_view(xp, frame, axis=0)[hop - 1::hop]  # (k, 3, frame)
    spec = np.fft.rfft(frames * wa, axis=2)  # (k, 3, m)
    mag = np.sqrt(np.sum(spec.real ** 2 + spec.imag ** 2, axis=1))
    s = spec.sum(axis=1)
    a = np.abs(s)
    unit = np.where(a > 0, s / np.where(a > 0, a, 1.0), 1.0)
    out = np.fft.irfft(mag * unit, n=frame, axis=1) * ws  # (k, frame)
    y = np.zeros(n + 2 * frame)
    for j in range(0, frame, hop):  # overlap-add, one hop-slice of every frame at a time
        idx = np.arange(out.shape[0]) * hop + hop - 1 + j
        y[idx[:, None] + np.arange(hop)] += out[:, j:j + hop]
    return y[:n]  # y[t] = output sample t - (frame - 1), as the node plays it out at tick t


@njit(cache=True)
def rocket_stream(x, frame, hop, wa, ws, y):
    ring = np.zeros((frame, 3))
    acc = np.zeros(frame)
    fr = np.zeros((3, frame))
    for t in range(x.shape[0]):
        ring[t % frame] = x[t]
        if (t + 1) % hop == 0:
            start = (t + 1) % frame
            for j in range(frame):
                for a in range(3):
                    fr[a, j] = ring[(start + j) % frame, a] * wa[j]
            spec = np.fft.rfft(fr)  # allocates
            m = spec.shape[1]
            comb = np.empty(m, np.complex128)  # allocates
            for k in range(m):
                sq = 0.0
                s = 0j
                for a in range(3):
                    sq += spec[a, k].real ** 2 + spec[a, k].imag ** 2
                    s += spec[a, k]
                h = abs(s)
                comb[k] = np.sqrt(sq) * (s / h if h > 0 else 1.0)
            out = np.fft.irfft(comb, frame)  # allocates
            for j in range(frame):
                acc[(start + j) % frame] += out[j] * ws[j]
        slot = (t + 1) % frame
        y[t] = acc[slot]
        acc[slot] = 0.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--runs", type=int, default=3)
    args = ap.parse_args()
    if importlib.util.find_spec("rocket_fft") is None:  # numba's np.fft support, for the "rocket" column
        raise SystemExit("bench_dft321.py compares with rocket-fft's np.fft inside numba: pip install -e '.[bench]'")
    x = np.random.default_rng(0).standard_normal((args.samples, 3))
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "g.yaml"
        path.write_text(GRAPH)
        print(f"{args.samples} ticks, 3 axes, Hann, hop = frame/2; median of {args.runs} paired runs")
        print(f"{'frame':>5} {'graph ns/tick':>14} {'graph+pc':>10} {'dft':>10} {'rocket':>10} {'numpy':>10} "
              f"{'graph/numpy':>12} {'dft/graph':>10} {'rocket/graph':>13} {'max diff':>10}")
        for frame in (32, 64, 128):
            hop = frame // 2
            over = {"red.frame": frame, "red.hop": hop}
            g = flowtex.load_graph(path, {**over, "red.correct_power": False})
            gpc = flowtex.load_graph(path, over)
            gd = flowtex.load_graph(path, {**over, "red.correct_power": False, "red.method": "dft"})
            wa, ws = windows(frame, hop, "hann")
            y_r = np.zeros(args.samples)
            g.run({"acc": x[:1000]})
            gpc.run({"acc": x[:1000]})
            gd.run({"acc": x[:1000]})
            rocket_stream(x[:1000], frame, hop, wa, ws, y_r[:1000])
            times: dict[str, list[float]] = {"graph": [], "pc": [], "dft": [], "rocket": [], "numpy": []}
            for _ in range(args.runs):
                t0 = time.perf_counter()
                y_g = g.run({"acc": x})["y"]
                t1 = time.perf_counter()
                gpc.run({"acc": x})
                t2 = time.perf_counter()
                y_d = gd.run({"acc": x})["y"]
                t3 = time.perf_counter()
                rocket_stream(x, frame, hop, wa, ws, y_r)
                t4 = time.perf_counter()
                y_n = numpy_stft(x, frame, hop, wa, ws)
                t5 = time.perf_counter()
                for key, dt in zip(times, (t1 - t0, t2 - t1, t3 - t2, t4 - t3, t5 - t4), strict=True):
                    times[key].append(dt)
            ns = {k: 1e9 * float(np.median(v)) / args.samples for k, v in times.items()}
            diff = max(np.max(np.abs(y - y_n)) for y in (y_g, y_d, y_r)) / np.max(np.abs(y_n))
            print(f"{frame:>5} {ns['graph']:>14.0f} {ns['pc']:>10.0f} {ns['dft']:>10.0f} {ns['rocket']:>10.0f} {ns['numpy']:>10.0f} "
                  f"{ns['graph'] / ns['numpy']:>12.2f} {ns['dft'] / ns['graph']:>10.2f} {ns['rocket'] / ns['graph']:>13.2f} {diff:>10.1e}")


if __name__ == "__main__":
    main()
