"""Per-tick cost of texture_lookup + arma_synth (orders 19/17) and spectral error vs lookup rate.

    python benchmarks/bench_texture.py [--ticks 1000000] [--repeats 5]

Prints (numbers, not assertions):

1. the synthesis kernel alone (flowtex.dsp.arma.arma_lattice_block), ns/tick,
   with the model changing every tick and with a fixed model; the lookup
   kernel alone (flowtex.dsp.interp.texture_lookup_block);
2. pieces: lsf_to_poly (AR + MA), the lattice-ladder coefficients of one
   model, locate; and the "floor": one plain numba loop doing the same
   arithmetic without any safety (triangle search with a last-triangle hint, barycentric LSF
   interpolation, float64 lsf_to_poly for AR and MA, direct-form synthesis);
3. the compiled graph speed/force -> texture_lookup -> arma_synth (output:
   the acceleration only), offline (``run``, blocks) and live
   (``step_block(1)`` per tick), median over repeats of >= 10^6 ticks each;
4. the table: for lookup every 1, 2, 4, 8 ticks, ns/tick, x floor, and the
   GFC between the output's Welch PSD and the time-averaged model PSD along
   the trajectory (the models of an every-1 lookup, i.e. the exact per-tick
   models, taken from a separate graph that also outputs them); then the
   targets for lookup every tick: <= 1.5 us, and <= 2.5x the floor, taken as
   the median ratio of graph and floor runs made back to back (the machine's
   load changes between runs; a pair sees the same load).

The machine is shared: run it when it is quiet and quote ``uptime`` with
the numbers (medians move by up to ~2x under load).

The input is a trajectory that sweeps speed and force across the model set's
hull at a few Hz, so the interpolated model changes on every tick.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from numba import njit

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.dsp.arma import arma_lattice_block, arma_psd, lattice_ladder_coefficients, new_state
from flowtex.dsp.lsf import lsf_to_poly, lsf_to_poly_new
from flowtex.dsp.rng import next_normal, seed_rng
from flowtex.dsp.spectral import gfc, welch_psd
from flowtex.dsp.triangulation import locate
from flowtex.fit.texture_graph import texture_builder

RATE = 1000.0

def trajectory(n: int, max_speed: float, max_force: float) -> dict[str, np.ndarray]:
    """Speed and force sweeping most of the hull (3.1 Hz and 1.7 Hz), never zero."""
    t = np.arange(n) / RATE
    speed = max_speed * (0.5 + 0.45 * np.sin(2 * np.pi * 3.1 * t))
    force = max_force * (0.5 + 0.45 * np.sin(2 * np.pi * 1.7 * t + 0.4))
    return {"speed": speed, "force": force}


# ----------------------------------------------------------------------------- the floor


@njit(cache=True, fastmath={"contract"})
def floor_kernel(pts, tris, ar_lsf, ma_lsf, var, gain, speed, force, lsf_a, lsf_m, a, c, ybuf, ebuf, si, sf, y):
    """Same arithmetic as lookup + synthesis, no safety: hint-first triangle search, LSF blend, lsf_to_poly, direct form.

    Deliberately lean: no clamping, NaN handling, repair, change detection or
    hull projection; direct-form synthesis (unbounded under model switching)
    with power-of-two circular buffers indexed by a mask; the same
    flowtex.dsp.lsf.lsf_to_poly (so any speed-up there lowers the floor too)
    and the same RNG.
    """
    p = ar_lsf.shape[1]
    q = ma_lsf.shape[1]
    hint = 0
    ntri = tris.shape[0]
    for t in range(speed.shape[0]):
        x = speed[t]
        z = force[t]
        w0 = w1 = w2 = 0.0
        for k in range(ntri):
            tri = hint + k
            if tri >= ntri:
                tri -= ntri
            i0, i1, i2 = tris[tri, 0], tris[tri, 1], tris[tri, 2]
            x0, y0 = pts[i0, 0], pts[i0, 1]
            det = (pts[i1, 1] - pts[i2, 1]) * (x0 - pts[i2, 0]) + (pts[i2, 0] - pts[i1, 0]) * (y0 - pts[i2, 1])
            w0 = ((pts[i1, 1] - pts[i2, 1]) * (x - pts[i2, 0]) + (pts[i2, 0] - pts[i1, 0]) * (z - pts[i2, 1])) / det
            w1 = ((pts[i2, 1] - y0) * (x - pts[i2, 0]) + (x0 - pts[i2, 0]) * (z - pts[i2, 1])) / det
            w2 = 1.0 - w0 - w1
            if w0 >= -1e-12 and w1 >= -1e-12 and w2 >= -1e-12:
                hint = tri
                break
        i0, i1, i2 = tris[hint, 0], tris[hint, 1], tris[hint, 2]
        for j in range(p):
            lsf_a[j] = w0 * ar_lsf[i0, j] + w1 * ar_lsf[i1, j] + w2 * ar_lsf[i2, j]
        for j in range(q):
            lsf_m[j] = w0 * ma_lsf[i0, j] + w1 * ma_lsf[i1, j] + w2 * ma_lsf[i2, j]
        v = w0 * var[i0] + w1 * var[i1] + w2 * var[i2]
        g = w0 * gain[i0] + w1 * gain[i1] + w2 * gain[i2]
        lsf_to_poly(lsf_a, a)
        lsf_to_poly(lsf_m, c)
        # direct form with circular buffers (64 entries, mask indexing) of past y and e
        e = math.sqrt(v) * next_normal(si, sf)
        pos = t & 63
        ebuf[pos] = e
        acc_ma = 0.0
        for j in range(q + 1):
            acc_ma += c[j] * ebuf[(pos - j) & 63]
        acc = g * acc_ma
        for i in range(1, p + 1):
            acc -= a[i] * ybuf[(pos - i) & 63]
        ybuf[pos] = acc
        y[t] = acc


def run_floor(ms, inputs) -> float:
    n = inputs["speed"].size
    pts = np.column_stack([ms.speeds, ms.forces])
    tris = ms.triangles.astype(np.int64)
    p, q = ms.ar_order, ms.ma_order
    si = np.zeros(5, np.int64)
    sf = np.zeros(1)
    seed_rng(si, sf, np.random.SeedSequence(1))
    args = (pts, tris, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, inputs["speed"], inputs["force"],
            np.zeros(p), np.zeros(q), np.zeros(p + 1), np.zeros(q + 1), np.zeros(64), np.zeros(64), si, sf, np.zeros(n))
    t0 = time.perf_counter()
    floor_kernel(*args)
    return (time.perf_counter() - t0) / n * 1e9


# ----------------------------------------------------------------------------- pieces


def synth_kernel_ns(ms, n: int) -> tuple[float, float]:
    """arma_lattice_block alone: (model changes every tick, fixed model) in ns/tick."""
    p, q = ms.ar_order, ms.ma_order
    m0, m1 = 0, 1
    a0, a1 = lsf_to_poly_new(ms.ar_lsf[m0]), lsf_to_poly_new(ms.ar_lsf[m1])
    c0, c1 = lsf_to_poly_new(ms.ma_lsf[m0]), lsf_to_poly_new(ms.ma_lsf[m1])
    ar = np.empty((n, p + 1))
    ma = np.empty((n, q + 1))
    ar[0::2], ar[1::2], ma[0::2], ma[1::2] = a0, a1, c0, c1
    gain = np.ones((n, 1))
    var = np.ones((n, 1))
    y = np.empty((n, 1))
    out = []
    for ar_, ma_ in ((ar, ma), (np.ascontiguousarray(np.broadcast_to(a0, ar.shape)), np.ascontiguousarray(np.broadcast_to(c0, ma.shape)))):
        s, si = new_state(p, q)
        seed_rng(si, s[0:1], np.random.SeedSequence(1))
        arma_lattice_block(s, si, ar_[:10], ma_[:10], gain[:10], var[:10], y[:10])  # compile / warm
        t0 = time.perf_counter()
        arma_lattice_block(s, si, ar_, ma_, gain, var, y)
        out.append((time.perf_counter() - t0) / n * 1e9)
    return out[0], out[1]


def graph_ns(graph, inputs, repeats: int) -> float:
    n = inputs["speed"].size
    graph.run({k: v[:100] for k, v in inputs.items()})  # warm
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        graph.run(inputs)
        times.append((time.perf_counter() - t0) / n * 1e9)
    return statistics.median(times)


def paired_ns(graph, ms, inputs, repeats: int) -> tuple[float, float, float]:
    """Graph and floor timed alternately (so both see the same machine load): medians of each and of the ratios."""
    graph.run({k: v[:100] for k, v in inputs.items()})  # warm
    run_floor(ms, {k: v[:100] for k, v in inputs.items()})
    n = inputs["speed"].size
    g_ns, f_ns = [], []
    for _ in range(repeats):
        f_ns.append(run_floor(ms, inputs))
        t0 = time.perf_counter()
        graph.run(inputs)
        g_ns.append((time.perf_counter() - t0) / n * 1e9)
    return statistics.median(g_ns), statistics.median(f_ns), statistics.median(g / f for g, f in zip(g_ns, f_ns, strict=True))


def live_ns(graph, inputs, n_live: int, repeats: int) -> float:
    """step_block(1) per tick with the inputs written into the live input views (the CAN loop's path)."""
    sp = graph.input_view("speed")
    fo = graph.input_view("force")
    speed, force = inputs["speed"], inputs["force"]
    times = []
    for _ in range(repeats):
        graph.reset()
        t0 = time.perf_counter()
        for t in range(n_live):
            sp[0] = speed[t]
            fo[0] = force[t]
            graph.step_block(1)
        times.append((time.perf_counter() - t0) / n_live * 1e9)
    return statistics.median(times)


def mean_model_psd(out: dict[str, np.ndarray], freqs: np.ndarray, stride: int = 25) -> np.ndarray:
    """Time average of the instantaneous model PSDs (one model every ``stride`` ticks)."""
    acc = np.zeros(freqs.size)
    idx = range(0, out["ar"].shape[0], stride)
    for t in idx:
        acc += arma_psd(out["ar"][t], out["ma"][t], float(out["gain"][t]), float(out["variance"][t]), freqs, RATE)
    return acc / len(idx)


def model_lsd_db(held: dict[str, np.ndarray], exact: dict[str, np.ndarray], freqs: np.ndarray, stride: int = 7) -> float:
    """Model-level spectral error of a slower lookup: mean over ticks of the RMS log-spectral distance (dB).

    Compares, tick by tick, the PSD of the model the synthesis actually used
    (``held``: outputs of an every-k lookup) with the PSD of the exact per-tick
    model (``exact``: the every-1 lookup). No estimation noise, unlike the
    GFC of the output. Every ``stride``-th tick (7: prime to 2, 4, 8, so all
    phases of the hold are sampled).
    """
    total = 0.0
    count = 0
    for t in range(0, held["ar"].shape[0], stride):
        a = arma_psd(held["ar"][t], held["ma"][t], float(held["gain"][t]), float(held["variance"][t]), freqs, RATE)
        b = arma_psd(exact["ar"][t], exact["ma"][t], float(exact["gain"][t]), float(exact["variance"][t]), freqs, RATE)
        if np.all(a > 0) and np.all(b > 0):
            total += float(np.sqrt(np.mean((10.0 * np.log10(a / b)) ** 2)))
            count += 1
    return total / max(count, 1)


@njit(cache=True)
def _pieces_kernel(which, lsf_a, lsf_m, a, c, ar, ma, k, cc, v, wa, wr, tri_tab, speed, force, w, vv):
    """One piece of the per-tick work, n times (which: 0 lsf_to_poly x2, 1 reflection/ladder coefficients, 2 locate)."""
    n = speed.shape[0]
    acc = 0.0
    hint = -1
    for t in range(n):
        if which == 0:
            lsf_a[0] = 0.05 + 1e-9 * (t & 7)  # a new vector every tick, as in the lookup
            lsf_to_poly(lsf_a, a)
            lsf_to_poly(lsf_m, c)
            acc += a[1] + c[1]
        elif which == 1:
            r = t & 3
            lattice_ladder_coefficients(ar[r], ma[r], 1.0 + 0.1 * r, k, cc, v, wa, wr)
            acc += v[1]
        else:
            hint = locate(tri_tab, speed[t], force[t], hint, w, vv)
            acc += w[0]
    return acc


def pieces_ns(ms, inputs, repeats: int, n: int = 200_000) -> tuple[float, float, float]:
    """Median ns of: lsf_to_poly for one AR + one MA vector; lattice-ladder coefficients of one model; locate of a moving query."""
    from flowtex.dsp.interp import T_OFF_MOD, T_OFF_TRI, pack_texture_table

    p, q = ms.ar_order, ms.ma_order
    L = max(p, q)
    tab = pack_texture_table(ms.speeds, ms.forces, ms.triangles, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, ms.max_speed, ms.max_force)
    tri_tab = np.ascontiguousarray(tab[int(tab[T_OFF_TRI]):int(tab[T_OFF_MOD])])
    ar = np.array([lsf_to_poly_new(ms.ar_lsf[i]) for i in range(4)])
    ma = np.array([lsf_to_poly_new(ms.ma_lsf[i]) for i in range(4)])
    args = [ms.ar_lsf[5].copy(), ms.ma_lsf[5].copy(), np.empty(p + 1), np.empty(q + 1), ar, ma,
            np.empty(L), np.empty(L), np.empty(L + 1), np.empty(L + 1), np.empty(L + 1), tri_tab,
            inputs["speed"][:n], inputs["force"][:n], np.empty(3), np.empty(3, np.int64)]
    out = []
    for which in range(3):
        _pieces_kernel(which, *args[:12], args[12][:10], args[13][:10], *args[14:])  # compile / warm
        times = []
        for _ in range(repeats):
            t0 = time.perf_counter()
            _pieces_kernel(which, *args)
            times.append((time.perf_counter() - t0) / args[12].size * 1e9)
        out.append(statistics.median(times))
    return out[0], out[1], out[2]


def lookup_kernel_ns(ms, inputs, repeats: int, interpolation: str = "variance") -> float:
    """texture_lookup_block alone on the trajectory (model changes every tick), median ns/tick."""
    from flowtex.dsp.interp import initial_state, pack_texture_table, texture_lookup_block

    tab = pack_texture_table(ms.speeds, ms.forces, ms.triangles, ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, ms.max_speed, ms.max_force,
                             interpolation=interpolation)
    n = inputs["speed"].size
    speed = inputs["speed"].reshape(n, 1)
    force = inputs["force"].reshape(n, 1)
    ar = np.empty((n, ms.ar_order + 1))
    ma = np.empty((n, ms.ma_order + 1))
    gain = np.empty((n, 1))
    var = np.empty((n, 1))
    times = []
    for r in range(repeats + 1):
        s, si = initial_state(ms.ar_order, ms.ma_order)
        m = 100 if r == 0 else n  # first round: compile / warm
        t0 = time.perf_counter()
        texture_lookup_block(tab, s, si, speed[:m], force[:m], ar[:m], ma[:m], gain[:m], var[:m])
        if r:
            times.append((time.perf_counter() - t0) / n * 1e9)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ticks", type=int, default=1_000_000)
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--live-ticks", type=int, default=200_000)
    parser.add_argument("--model-error-ticks", type=int, default=100_000, help="ticks compared model by model (LSD column)")
    args = parser.parse_args()
    n = args.ticks

    ms = cork_like_model_set()
    print(f"model set: {ms.material}, AR {ms.ar_order} / MA {ms.ma_order}, {ms.num_models} models, {len(ms.triangles)} triangles; "
          f"{n} ticks per run, median of {args.repeats} runs")
    inputs = trajectory(n, ms.max_speed, ms.max_force)

    changing, fixed = synth_kernel_ns(ms, n)
    print(f"synthesis kernel alone (arma_lattice_block): {changing:7.1f} ns/tick model changing every tick, {fixed:7.1f} ns/tick fixed model")
    lookup = lookup_kernel_ns(ms, inputs, args.repeats)
    print(f"lookup kernel alone (texture_lookup_block, moving query): {lookup:7.1f} ns/tick")
    for rule in ("power", "log_power"):   # the output power of each blended filter, per lookup (docs/texture.md)
        t = lookup_kernel_ns(ms, inputs, args.repeats, rule)
        print(f"  with interpolation: {rule}: {t:7.1f} ns/tick ({t / lookup:.2f}x variance, same run)")
    l2p, coef, loc = pieces_ns(ms, inputs, args.repeats)
    print(f"pieces: lsf_to_poly AR {ms.ar_order} + MA {ms.ma_order} {l2p:6.1f} ns; reflection + ladder coefficients of one model "
          f"{coef:6.1f} ns; locate (moving query) {loc:5.1f} ns")

    # The one texture graph (flowtex.fit.texture_graph), built with the model set in memory.
    # Reference models: the every-1 lookup's per-tick models (a separate graph, so that the timed graphs
    # only output the acceleration, as a renderer would).
    ref_out = texture_builder(ms, RATE, model_outputs=True).build().run(inputs)
    freqs, _ = welch_psd(ref_out["accel"], RATE, nperseg=1024)
    reference = mean_model_psd(ref_out, freqs)
    m = min(args.model_error_ticks, n)
    exact = {k: ref_out[k][:m] for k in ("ar", "ma", "gain", "variance")}
    del ref_out
    rows = []
    for every in (1, 2, 4, 8):
        graph = texture_builder(ms, RATE, every=every).build()
        if every == 1:
            ns, floor, ratio = paired_ns(graph, ms, inputs, args.repeats)
        else:
            ns = graph_ns(graph, inputs, args.repeats)
        live = live_ns(graph, inputs, min(args.live_ticks, n), max(1, args.repeats // 2))
        y = graph.run(inputs)["accel"]
        _, psd = welch_psd(y, RATE, nperseg=1024)
        fit = gfc(np.sqrt(psd), np.sqrt(reference))
        held = texture_builder(ms, RATE, every=every, model_outputs=True).build().run({k: v[:m] for k, v in inputs.items()})
        lsd = model_lsd_db(held, exact, freqs)
        rows.append((every, ns, live, fit, lsd, float(np.max(np.abs(y))), float(np.sqrt(np.mean(y * y)))))

    print(f"floor (plain numba, no safety: triangle search + LSF blend + lsf_to_poly x2 + direct form): {floor:7.1f} ns/tick")
    print()
    print("graph speed/force -> texture_lookup (every k ticks) -> arma_synth, output: acceleration only")
    print("(ns/tick: offline run(), blocks; live: step_block(1) per tick from Python, the CAN loop's path)")
    print("(x floor: ns/tick over the floor's median; the floor runs alternate with the every-1 graph's)")
    print(f"{'every':>5} {'ns/tick':>9} {'x floor':>8} {'GFC':>8} {'model LSD dB':>13} {'live ns/tick':>13} {'peak/rms':>9}")
    for every, ns, live, fit, lsd, peak, rms in rows:
        print(f"{every:>5} {ns:9.1f} {ns / floor:8.2f} {fit:8.5f} {lsd:13.5f} {live:13.1f} {peak / rms:9.2f}")
    one = rows[0][1]
    print()
    print(f"target: lookup every tick <= 1500 ns/tick ... {'met' if one <= 1500 else 'NOT met'} ({one:.0f} ns/tick)")
    print(f"target: lookup every tick <= 2.5 x floor .... {'met' if ratio <= 2.5 else 'NOT met'} "
          f"({ratio:.2f} x floor: median of {args.repeats} graph/floor ratios, each pair run back to back)")
    print("reference: HaTT's C++ renderer ~4000 ns/tick on this machine (issue 3; not measured here)")
    print("GFC: Welch PSD of the output vs the time-averaged per-tick model PSD (models of the every-1 lookup); 1 = identical shape;")
    print("     every 1 shows the Welch estimation floor. model LSD: mean RMS log-spectral distance (dB) between the model a")
    print(f"     slower lookup holds and the exact per-tick model, over the first {min(args.model_error_ticks, n)} ticks (0 for every 1).")
    print("peak/rms: whole-run peak over whole-run RMS of a non-stationary output (not the switching bound; see tests).")


if __name__ == "__main__":
    main()
