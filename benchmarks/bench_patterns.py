"""Patterned textures and compliance: per-tick cost, fit cost, and 004 Table 1-style fit figures.

    PYTHONPATH=. python benchmarks/bench_patterns.py [--ticks 200000] [--repeats 5]

Prints (numbers, not assertions; the machine is shared, quote ``uptime``):

1. ``patterned_texture``'s kernel (flowtex.dsp.patterns.pattern_block) with 8 ring-downs
   of order 6 always active (a feature crossed every 5 ticks, slots full), ns/tick,
   beside a plain numba loop of the same arithmetic (8 fixed direct-form-II-transposed
   filters, an impulse every 5 ticks, no crossing search and no slot bookkeeping), the
   ratio of the two, and the node's error against the float64 scipy reference;
2. Prony + guarded Steiglitz-McBride per segment (orders 2..8, as ``flowtex fit pattern``),
   ms/segment, with numpy's lstsq (our default) and with scipy.linalg.lstsq on the same
   equations, and plain Prony; with each configuration's SAD against the noise-free truth;
3. ``compliance_estimator``'s kernel, ns/tick, on simulated stroking (fit redone on every
   binned tick);
4. a 004 Table 1-style table for the synthetic grating (2 mm, 180 Hz, 5 % noise) at three
   scanning speeds: segments, segments per mm, mean filter order M + 1, mean SAD (m/s^2).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np
import scipy.linalg
from numba import njit

from flowtex.datasets.patterns import patterned_recording, render_features, resonance, stroking_recording
from flowtex.dsp.compliance import compliance_params, new_state
from flowtex.dsp.patterns import RING_DECAY, pattern_block, pattern_params, pattern_state
from flowtex.dsp.prony import fit_iir, impulse_response, lstsq_numpy, ring_length, sad
from flowtex.fit.pattern import fit_pattern
from flowtex.nodes.compliance import _compliance

RATE = 1000.0
ORDER = 6
SLOTS = 8


def _filters(k: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(0)
    b = np.zeros((k, ORDER + 1))
    a = np.zeros((k, ORDER + 1))
    for i in range(k):
        poles = [r * np.exp(s * 1j * w) for r, w in zip(rng.uniform(0.9, 0.97, 3), rng.uniform(0.3, 2.5, 3), strict=True)
                 for s in (1, -1)]
        a[i] = np.real(np.poly(poles))
        b[i] = rng.standard_normal(ORDER + 1)
    return b, a


@njit(cache=True)
def _plain(b, a, every, y):
    """8 fixed filters (direct form II transposed), filter j kicked every `every` ticks in turn; the floor."""
    z = np.zeros((b.shape[0], b.shape[1] - 1))
    order = b.shape[1] - 1
    nxt = 0
    for t in range(y.shape[0]):
        acc = 0.0
        kick = t % every == 0
        for j in range(b.shape[0]):
            u = 1.0 if kick and j == nxt else 0.0
            out = b[j, 0] * u + z[j, 0]
            for i in range(order - 1):
                z[j, i] = b[j, i + 1] * u - a[j, i + 1] * out + z[j, i + 1]
            z[j, order - 1] = b[j, order] * u - a[j, order] * out
            acc += out
        if kick:
            nxt = (nxt + 1) % b.shape[0]
        y[t, 0] = acc


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def bench_render(ticks: int, repeats: int) -> None:
    every = 5
    spacing = 0.3  # mm; at 60 mm/s a feature every 5 ticks
    k = int(ticks * 60.0 / RATE / spacing) + 2
    b, a = _filters(k)
    lengths = np.array([ring_length(b[i], a[i], RING_DECAY) for i in range(k)], float)
    positions = spacing * (np.arange(k) + 0.5)
    amps = np.ones(k)
    params = pattern_params(np.array([1.0, 0, 0]), np.zeros(3), positions, amps, lengths, b, a, SLOTS)
    x = 60.0 * np.arange(ticks) / RATE
    pos = np.ascontiguousarray(np.column_stack([x, np.zeros(ticks), np.zeros(ticks)]))
    contact = np.ones((ticks, 1))
    y = np.zeros((ticks, 1))

    def node():
        s, si = pattern_state(ORDER, SLOTS)
        pattern_block(params, s, si, pos, contact, y)

    y2 = np.zeros((ticks, 1))
    bs, as_ = np.ascontiguousarray(b[:SLOTS]), np.ascontiguousarray(a[:SLOTS])

    def plain():
        _plain(bs, as_, every, y2)

    node()
    plain()
    tn, tp = _best(node, repeats), _best(plain, repeats)
    print(f"1. patterned_texture kernel, {SLOTS} active ring-downs of order {ORDER}: {tn / ticks * 1e9:7.1f} ns/tick")
    print(f"   plain numba loop, same arithmetic:                  {tp / ticks * 1e9:7.1f} ns/tick   ratio {tn / tp:.2f}x")
    # error against float64 scipy, on a short stretch with enough slots for every ring-down (no replacement)
    n = 3000
    p64 = pattern_params(np.array([1.0, 0, 0]), np.zeros(3), positions, amps, lengths, b, a, 256)
    s, si = pattern_state(ORDER, 256)
    ys = np.zeros((n, 1))
    pattern_block(p64, s, si, pos[:n].copy(), contact[:n].copy(), ys)
    ref = render_features(x[:n], positions, amps, [(b[i], a[i]) for i in range(k)])
    print(f"   node vs float64 scipy reference (256 slots): max |error| {np.max(np.abs(ys[:, 0] - ref)):.2e} m/s^2 "
          f"(ring-downs stop at {RING_DECAY:g} of their peak)")


def bench_fit(repeats: int) -> None:
    rng = np.random.default_rng(3)
    b, a = resonance(180.0, 0.006, RATE)
    b2, a2 = resonance(310.0, 0.003, RATE)
    truth = impulse_response(b, a, 34) + 0.4 * impulse_response(b2, a2, 34)  # one 2 mm segment at 60 mm/s
    segs = [truth + 0.05 * np.std(truth) * rng.standard_normal(truth.size) for _ in range(20)]
    configs = [("smb + numpy lstsq (default)", dict(method="smb", solver=lstsq_numpy)),
               ("smb + scipy.linalg.lstsq", dict(method="smb", solver=lambda A, y: scipy.linalg.lstsq(A, y)[0])),
               ("plain Prony + numpy lstsq", dict(method="prony", solver=lstsq_numpy))]
    print("2. one segment (34 samples, 5 % noise), orders 2..8, median over 20 segments:")
    for name, kw in configs:
        fits = [fit_iir(s, range(2, 9), **kw) for s in segs]
        t = _best(lambda kw=kw: [fit_iir(s, range(2, 9), **kw) for s in segs], max(1, repeats // 2)) / len(segs)
        err = statistics.median(sad(truth, f.b, f.a) for f in fits)
        print(f"   {name:30s} {t * 1e3:7.2f} ms/segment   SAD vs truth {err:.4f} (truth mean |h| {np.mean(np.abs(truth)):.3f})")
    print("   at the true orders (4, 4) only:")
    for name, kw in configs:
        fits = [fit_iir(s, [4], **kw) for s in segs]
        t = _best(lambda kw=kw: [fit_iir(s, [4], **kw) for s in segs], max(1, repeats // 2)) / len(segs)
        err = statistics.median(sad(truth, f.b, f.a) for f in fits)
        print(f"   {name:30s} {t * 1e3:7.2f} ms/segment   SAD vs truth {err:.4f}")


def bench_compliance(ticks: int, repeats: int) -> None:
    rec = stroking_recording(0.5, seconds=ticks / RATE, seed=1)
    p = np.append(compliance_params(RATE, 0.3, 3.0, k_g=0.5), 0.5)
    f = rec["force"].reshape(-1, 1).copy()
    acc = rec["accel"].reshape(-1, 1).copy()
    c = np.ones((ticks, 1))
    outs = [np.zeros((ticks, 1)) for _ in range(3)]

    def run():
        s = np.concatenate([new_state(), [np.nan, np.nan, 0.0, 0.0, 0.0]])
        _compliance(p, s, np.zeros(1, np.int64), f, acc, c, *outs)

    run()
    t = _best(run, repeats)
    print(f"3. compliance_estimator kernel: {t / ticks * 1e9:7.1f} ns/tick (k_c at the end {outs[0][-1, 0]:.4f}, truth 0.5)")


def table1() -> None:
    print("4. 004 Table 1-style figures, synthetic grating (2 mm, 180 Hz, 6 ms decay, 5 % noise), 2 s each:")
    print("   speed mm/s  segments  length mm  segments/mm  mean M+1  mean SAD m/s^2  (truth: 0.5 features/mm)")
    for speed in (30.0, 60.0, 120.0):
        rec = patterned_recording(seconds=2.0, speed_mm_s=speed, seed=1)
        pat = fit_pattern(rec["accel"], rec["position"], RATE)
        m = pat.metadata
        length = speed * 2.0
        print(f"   {speed:10.0f}  {m['segments']:8d}  {length:9.0f}  {m['segments'] / length:11.3f}  {m['mean_order'] + 1:8.2f}  "
              f"{m['mean_sad']:14.4f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=200_000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    bench_render(args.ticks, args.repeats)
    bench_fit(args.repeats)
    bench_compliance(args.ticks, args.repeats)
    table1()


if __name__ == "__main__":
    main()
