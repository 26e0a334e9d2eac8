"""Audio-rate output (issue 19), side by side with its baselines.

    python benchmarks/bench_audio.py [--no-jack | --live-only] [--quick] [--laptop]

1. Cost: ns per audio sample of the bundled texture (graphs/live_audio.yaml over
   graphs/data/exploration.npz: the graph at 1 kHz plus the band-limited
   interpolator) at 8 and 48 kHz, against a plain numba loop of the same
   arithmetic's core (ARMA synthesis of one fixed model at 1 kHz and the same
   polyphase FIR up to the audio rate; no model lookup, speed, contact or friction,
   so it is a floor), and the other design: synthesis at the audio rate from models
   resampled to it (``flowtex models resample``, at most 5x: 5 kHz).
2. Images: power above 0.55 x the model set's rate (550 Hz) relative to the total,
   for this interpolator, the same filter with linear phase, linear interpolation,
   a zero-order hold of the 1 kHz signal, and the 5 kHz synthesis; with each one's
   delay at 50 Hz.
3. Live against a JACK server with the dummy backend (jackd2; real-time in the ``--rt`` rows only), the bundled example at
   8 kHz / 64, 44.1 kHz / 256 and 48 kHz / 128, each idle and with one core kept busy
   by another process, without and with ``--rt``, the map's ``margin_ms`` beside each
   row (the default 10 ms growing up to 15 ms after a stall it did not absorb, beside a fixed 10 ms; a fixed 2 ms, about
   the old margin, as the baseline; a fixed 0.5 ms with ``--rt`` for low latency) and the margin at the session's
   end: underruns, resyncs, missed deadlines, sensor-to-DAC latency p50/p99/max. The machine is shared: the load average is printed beside
   every row (``--quick``: at most 5 s a row). ``--laptop``: only the default 8 kHz / 64 rows, with jackd
   real-time and flowtex without ``--rt``, as on a laptop whose sound server rtkit makes real-time while
   flowtex runs unprivileged.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
from numba import njit
from scipy import signal

REPO = Path(__file__).resolve().parents[1]
GRAPH = REPO / "graphs" / "live_audio.yaml"
REC = REPO / "graphs" / "data" / "exploration.npz"
MAP = REPO / "graphs" / "devices" / "example_audio_map.yaml"
DBC = REPO / "graphs" / "devices" / "example.dbc"
MODELS = REPO / "graphs" / "data" / "synthetic_texture.json"


def power_above(y: np.ndarray, rate: float, f0: float = 550.0) -> float:
    f, p = signal.welch(np.asarray(y, dtype=np.float64), rate, nperseg=4096)
    return float(p[f > f0].sum() / p.sum())


@njit(cache=True)
def plain_loop(a, c, g, x, branches, out):
    """ARMA(p, q) of white noise x at the tick rate, then polyphase interpolation (branches: up x taps, oldest first)."""
    p, q = a.size - 1, c.size - 1
    up, taps = branches.shape
    e_hist = np.zeros(q + 1)
    y_hist = np.zeros(p + 1)
    hist = np.zeros(taps)
    for k in range(x.size):
        for j in range(q, 0, -1):
            e_hist[j] = e_hist[j - 1]
        e_hist[0] = x[k]
        acc = 0.0
        for j in range(q + 1):
            acc += c[j] * e_hist[j]
        acc *= g
        for j in range(1, p + 1):
            acc -= a[j] * y_hist[j - 1]
        for j in range(p, 0, -1):
            y_hist[j] = y_hist[j - 1]
        y_hist[0] = acc
        for j in range(taps - 1):
            hist[j] = hist[j + 1]
        hist[taps - 1] = acc
        for r in range(up):
            s = 0.0
            for j in range(taps):
                s += branches[r, j] * hist[j]
            out[k * up + r] = np.float32(s)


def best_of(fn, repeats: int = 3) -> float:
    best = float("inf")
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def cost_and_images() -> None:
    from flowtex.dsp.audio_interp import Interpolator, low_frequency_delay
    from flowtex.dsp.filter_design import resampling_fir
    from flowtex.dsp.resample_stream import stream_params
    from flowtex.graph.compiled import load_graph
    from flowtex.io.modelset import load_model_set
    from flowtex.io.recordings import load_recording

    rec = load_recording(REC)
    graph = load_graph(GRAPH)
    inputs = {n: rec.arrays[n] for n in graph.inputs}
    graph.run(inputs, progress=False)
    n = rec.samples
    t_graph = best_of(lambda: graph.run(inputs, progress=False))
    vib = np.ascontiguousarray(graph.run(inputs, progress=False)["vibration"].reshape(-1, 1))
    ms = load_model_set(MODELS)
    from flowtex.dsp.lsf import lsf_to_poly_new

    mid = len(ms.variance) // 2
    a, c = lsf_to_poly_new(ms.ar_lsf[mid]), lsf_to_poly_new(ms.ma_lsf[mid])
    noise = np.random.default_rng(0).standard_normal(n) * np.sqrt(ms.variance[mid])
    print(f"1. cost per audio sample, texture over {n} ticks ({n / 1000:g} s), best of 3")
    print(f"   {'rate':>6}  {'flowtex graph+interp':>22}  {'plain numba loop':>17}  {'ratio':>6}")
    for rate in (8000, 48000):
        up = rate // 1000
        it = Interpolator(up, 1, [1.5], [-1.0], [1.0])
        out = np.zeros((n * up, 1), dtype=np.float32)
        it.render(vib, out)
        t_interp = best_of(lambda it=it, out=out: (it.reset(), it.render(vib, out)))
        coef = stream_params(it.h, up, 1)[4:].reshape(up, -1)
        flat = np.zeros(n * up, dtype=np.float32)
        plain_loop(a, c, float(ms.gain[mid]), noise, coef, flat)
        t_plain = best_of(lambda coef=coef, flat=flat: plain_loop(a, c, float(ms.gain[mid]), noise, coef, flat))
        ours = (t_graph + t_interp) / (n * up) * 1e9
        base = t_plain / (n * up) * 1e9
        print(f"   {rate:>6}  {ours:>19.1f} ns  {base:>14.1f} ns  {ours / base:>6.2f}"
              f"   (graph {t_graph / n * 1e9:.0f} ns/tick, interpolator {t_interp / (n * up) * 1e9:.1f} ns/sample)")
    # the other design: the graph at 5 kHz on models resampled to 5 kHz
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        subprocess.run([sys.executable, "-m", "flowtex", "models", "resample", str(MODELS), "--rate", "5000", "-o",
                        str(tmp / "m5k.json")], check=True, capture_output=True)
        subprocess.run([sys.executable, "-m", "flowtex", "resample", str(REC), "--rate", "5000", "-o", str(tmp / "rec5k.npz")],
                       check=True, capture_output=True)
        text = GRAPH.read_text().replace("rate: 1000", "rate: 5000").replace("data/synthetic_texture.json", str(tmp / "m5k.json"))
        (tmp / "g5k.yaml").write_text(text)
        g5 = load_graph(tmp / "g5k.yaml")
        rec5 = load_recording(tmp / "rec5k.npz")
        in5 = {k: rec5.arrays[k] for k in g5.inputs}
        y5 = g5.run(in5, progress=False)["vibration"].reshape(-1)
        t5 = best_of(lambda: g5.run(in5, progress=False))
        it5 = Interpolator(5, 1, [1.0], [-10.0], [10.0])
        o5 = np.zeros((n * 5, 1), dtype=np.float32)
        t5i = best_of(lambda: (it5.reset(), it5.render(vib, o5)))
        print(f"   {5000:>6}  graph at 5 kHz on resampled models (orders {g5_orders(tmp / 'm5k.json')}): {t5 / y5.size * 1e9:.1f} ns/sample; "
              f"1 kHz graph + interpolator: {(t_graph + t5i) / (n * 5) * 1e9:.1f} ns/sample")
    print("\n2. images: power above 550 Hz / total, and delay at 50 Hz (bundled example)")
    up = 8
    h_lin = resampling_fir(up, 1, 60.0, 0.8)
    rows = []
    it = Interpolator(up, 1, [1.0], [-10.0], [10.0])
    o = np.zeros((n * up, 1), dtype=np.float32)
    it.render(vib, o)
    rows.append(("minimum-phase polyphase (flowtex)", power_above(o[:, 0], 8000), low_frequency_delay(it.h, 8000)))
    rows.append(("same filter, linear phase", power_above(signal.upfirdn(up * h_lin, vib[:, 0], up), 8000), (h_lin.size - 1) / 2 / 8000))
    t = np.arange(n * up) / up
    rows.append(("linear interpolation", power_above(np.interp(t, np.arange(n), vib[:, 0]), 8000), 1e-3))
    rows.append(("zero-order hold (baseline)", power_above(np.repeat(vib[:, 0], up), 8000), 0.5e-3))
    rows.append(("synthesis at 5 kHz, resampled models", power_above(y5, 5000), 0.0))
    zoh = rows[3][1]
    for name, pa, d in rows:
        print(f"   {name:<40} {pa:10.2e}  ({pa / zoh:8.1e} x hold)  delay {d * 1e3:5.2f} ms")


def g5_orders(path: Path) -> str:
    d = json.loads(path.read_text())
    return f"{d['ar_order']}/{d['ma_order']}"


@contextlib.contextmanager
def jack_server(name: str, rate: int, period: int, realtime: bool = False, busy: bool = False) -> Iterator[None]:
    """A JACK server named ``name`` on the dummy backend (no sound hardware, paced in real time), given 1.5 s to
    start, and (``busy``) one CPU-bound process beside it; both stopped on exit. jackd runs without real-time
    scheduling, as an unprivileged laptop runs it, or (``realtime``) with it, as a machine that grants flowtex
    SCHED_FIFO, or a laptop whose sound server rtkit makes real-time, runs it (jackd's default; its clients'
    process threads get it)."""
    mode = "--realtime" if realtime else "--no-realtime"
    jackd = subprocess.Popen(["jackd", mode, "-n", name, "-d", "dummy", "-r", str(rate), "-p", str(period)],
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None  # one core kept busy
    try:
        time.sleep(1.5)
        yield
    finally:
        if hog is not None:
            hog.kill()
            hog.wait()
        jackd.terminate()
        jackd.wait(10)


def example_map(folder: Path, rate: int, period: int, margin_ms: float, margin_max_ms: float | None = None) -> Path:
    """The bundled audio map with another audio rate, block and margin (and largest margin: None keeps the map's, at
    least ``margin_ms``), written to ``folder``."""
    m = folder / "m.yaml"
    text = MAP.read_text().replace("rate: 8000 ", f"rate: {rate} ").replace("block: 64 ", f"block: {period} ")
    most = max(15.0, margin_ms) if margin_max_ms is None else margin_max_ms
    text = text.replace("margin_max_ms: 15 ", f"margin_max_ms: {most:g} ")
    m.write_text(text.replace("margin_ms: 10 ", f"margin_ms: {margin_ms:g} "))
    return m


def jack_session(rate: int, period: int, seconds: float, margin_ms: float, most_ms: float, rt: bool, busy: bool,
                 server_rt: bool | None = None) -> dict:
    """One ``flowtex live`` session of the bundled example against a private JACK dummy server; its ``--stats``.
    ``server_rt``: jackd real-time (None: as ``rt``)."""
    name = f"flowtex-bench-{os.getpid()}-{rate}-{period}-{int(rt)}-{int(busy)}"
    env = {**os.environ, "JACK_DEFAULT_SERVER": name, "JACK_NO_START_SERVER": "1"}
    with jack_server(name, rate, period, realtime=rt if server_rt is None else server_rt, busy=busy), \
            tempfile.TemporaryDirectory() as tmp:
        m = example_map(Path(tmp), rate, period, margin_ms, most_ms)
        stats = Path(tmp) / "stats.json"
        load = os.getloadavg()[0]
        subprocess.run([sys.executable, "-m", "flowtex", "live", str(GRAPH), "--bus", "virtual", "--dbc", str(DBC), "--map", str(m),
                        "--simulate", str(REC), "--duration", str(seconds), "--stats", str(stats), "--quiet",
                        *(["--rt"] if rt else [])], env=env, check=True, timeout=600)
        s = json.loads(stats.read_text())
        s["load"] = (load + os.getloadavg()[0]) / 2
        return s


LIVE_ROWS = [  # (rate, period, margin_ms, margin_max_ms, --rt, seconds)
    (8000, 64, 2.0, 2.0, False, 10.0),     # baseline: about the old margin (one tick + 1 ms = 2 ms at 8 kHz), fixed
    (8000, 64, 10.0, 10.0, False, 60.0),   # the last round's default: a fixed 10 ms margin
    (8000, 64, 10.0, 15.0, False, 60.0),   # the default: 10 ms, growing up to 15 ms after a stall it did not absorb
    (8000, 64, 10.0, 15.0, True, 10.0),
    (8000, 64, 0.5, 0.5, True, 10.0),
    (44100, 256, 10.0, 15.0, False, 10.0),
    (44100, 256, 0.5, 0.5, True, 10.0),
    (48000, 128, 10.0, 15.0, False, 10.0),
    (48000, 128, 0.5, 0.5, True, 10.0),    # low latency when asked: goal p99 <= 10 ms, 0 underruns on an idle machine
]
LAPTOP_ROWS = [  # a laptop's sound server runs real-time (rtkit grants it, and its clients' callbacks), flowtex does not
    (8000, 64, 10.0, 15.0, False, 60.0),
]
"""``--laptop``: these rows only, jackd real-time and ``flowtex live`` without ``--rt``."""


def live(quick: bool = False, laptop: bool = False) -> None:
    if shutil.which("jackd") is None:
        print("\n3. live: jackd not installed (apt-get install jackd2 libportaudio2); skipped")
        return
    print("\n3. live against JACK's dummy backend (flowtex live, bundled example, simulated CAN device); 'busy': one other "
          "process keeps a core busy. underruns = late callbacks (the loop outlasted the margin) + device underflows (JACK's xruns)")
    print(f"   {'rate/period':>12} {'margin (max) end':>18} {'rt':>3} {'load':>5} {'s':>4} {'cpu':>5}  {'underruns':>15}  "
          f"{'resyncs':>7}  {'missed':>6}  {'latency ms p50 / p99 / max':>27}")
    if laptop:
        print("   (--laptop: jackd real-time, flowtex without --rt)")
    for rate, period, margin, most, rt, seconds in LAPTOP_ROWS if laptop else LIVE_ROWS:
        seconds = min(seconds, 5.0) if quick else seconds
        for busy in (False, True):
            s = jack_session(rate, period, seconds, margin, most, rt, busy, server_rt=True if laptop else None)
            a = s["audio"]
            lat = a["latency_ms"]
            grown = f"{margin:g} ({most:g}) {a['margin_end_ms']:g}ms"
            print(f"   {rate:>6}/{period:<5} {grown:>18} {'yes' if rt else 'no':>3} {s['load']:>5.1f} {seconds:>4g} "
                  f"{'busy' if busy else 'idle':>5}  {a['underruns']:>5} ({a['late_callbacks']} + {a['device_underflows']})  "
                  f"{len(a['resyncs']):>7}  {s['missed']:>6}  {lat['p50']:>8.2f} / {lat['p99']:>6.2f} / {lat['max']:>7.1f}",
                  flush=True)


if __name__ == "__main__":
    if "--live-only" not in sys.argv:
        cost_and_images()
    if "--no-jack" not in sys.argv:
        live(quick="--quick" in sys.argv, laptop="--laptop" in sys.argv)
