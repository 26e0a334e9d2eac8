"""Where the live audio loop's stalls come from: one traced ``flowtex live`` session of the bundled audio example.

    python benchmarks/trace_audio_stalls.py [--rate 8000] [--period 64] [--margin 10] [--margin-max 15] [--seconds 20] [--busy] [--rt]

Starts a private JACK dummy server (as benchmarks/bench_audio.py does), then runs
``flowtex live`` in this process with the loop's parts wrapped so that every phase
of every tick is timestamped (perf_counter and the loop thread's CPU time) and every
wait for a deadline samples the thread's ``getrusage(RUSAGE_THREAD)`` (page faults,
voluntary and involuntary context switches); the audio callback's start, length and
gap to the previous one are kept too. At the end it prints every tick that was
late by more than ``--late-ms`` (default 1 ms) or skipped deadlines, with the phases
of it and of the tick before it that took longest (wall and CPU time), the thread's
context switches and page faults over those ticks, and the callbacks around it.

Reading it: a phase whose wall time far exceeds its CPU time with *involuntary*
switches waited for a core (the scheduler); with *voluntary* switches it blocked (the
GIL held by another thread, a lock, I/O); wall close to CPU time is work of ours (a
compile, a first-seen code path, a collection). The wrappers cost about a
microsecond per phase; they do not change what stalls.
"""

from __future__ import annotations

import argparse
import os
import resource
import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))
sys.path.insert(0, str(REPO / "benchmarks"))
from bench_audio import DBC, GRAPH, REC, example_map, jack_server  # noqa: E402

PHASES = ["wait", "sleep", "prepare", "receive", "compute", "send", "push", "check", "pace", "publish", "collect", "other"]
P = {name: i for i, name in enumerate(PHASES)}
CAP = 1 << 22


class Trace:
    """Preallocated event rows: (phase, start ns, wall ns, thread-CPU ns) for the loop; rusage per wait; callbacks."""

    def __init__(self) -> None:
        self.ev = np.zeros((CAP, 4), dtype=np.int64)
        self.n = 0
        self.ru = np.zeros((CAP // 8, 5), dtype=np.int64)  # perf ns, minflt, majflt, nvcsw, nivcsw
        self.nru = 0
        self.cb = np.zeros((CAP // 8, 5), dtype=np.int64)  # start ns, wall ns, thread-CPU ns, underflow flag, PA time ns
        self.ncb = 0
        self.waits = np.zeros((CAP // 8, 3), dtype=np.int64)  # return ns, lateness ns, deadlines skipped
        self.signatures: dict[str, int] = {}
        self.nw = 0

    def wrap(self, phase: str, fn):
        code, ev, pc, tt = P[phase], self.ev, time.perf_counter_ns, time.thread_time_ns

        def traced(*a, **kw):
            t0, c0 = pc(), tt()
            try:
                return fn(*a, **kw)
            finally:
                i = self.n
                if i < CAP:
                    ev[i, 0], ev[i, 1], ev[i, 2], ev[i, 3] = code, t0, pc() - t0, tt() - c0
                    self.n = i + 1
        return traced

    def rusage(self) -> None:
        r = resource.getrusage(resource.RUSAGE_THREAD)
        if self.nru < self.ru.shape[0]:
            self.ru[self.nru] = (time.perf_counter_ns(), r.ru_minflt, r.ru_majflt, r.ru_nvcsw, r.ru_nivcsw)
            self.nru += 1


def install(trace: Trace) -> None:
    """Wrap the live loop's parts (module-level names of flowtex.runtime.live) so that they record into ``trace``."""
    from flowtex.runtime import audio as audio_mod
    from flowtex.runtime import live

    base_clock = live.DeadlineClock

    class TracedClock(base_clock):
        def __init__(self, *a, **kw):
            trace.signatures = signature_counts()  # the loop starts after this: what compiles later, compiled live
            kw["sleep"] = trace.wrap("sleep", time.sleep)
            if kw.get("prepare") is not None:
                kw["prepare"] = trace.wrap("prepare", kw["prepare"])
            super().__init__(*a, **kw)
            self._wait = trace.wrap("wait", super().wait)

        def wait(self):
            trace.rusage()
            late = self._wait()
            i = trace.nw
            if i < trace.waits.shape[0]:
                trace.waits[i] = (time.perf_counter_ns(), late, self.skipped)
                trace.nw = i + 1
            return late

    live.DeadlineClock = TracedClock
    def traced_factory(make, phase):
        return lambda *a, **kw: trace.wrap(phase, make(*a, **kw))

    for name, phase in (("tick_compute", "compute"), ("receiver", "receive"), ("sender", "send")):
        setattr(live, name, traced_factory(getattr(live, name), phase))
    make_device = live.in_process_device

    def device(*a, **kw):
        bus, dev_bus, dev = make_device(*a, **kw)
        dev.publish, dev.collect = trace.wrap("publish", dev.publish), trace.wrap("collect", dev.collect)
        return bus, dev_bus, dev
    live.in_process_device = device
    out = audio_mod.AudioOutput
    for name in ("push", "check", "pace"):
        setattr(out, name, trace.wrap(name, getattr(out, name)))
    callback = out._callback

    def traced_callback(self, *a):
        t0, c0 = time.perf_counter_ns(), time.thread_time_ns()
        callback(self, *a)
        i = trace.ncb
        if i < trace.cb.shape[0]:
            trace.cb[i] = (t0, time.perf_counter_ns() - t0, time.thread_time_ns() - c0, bool(a[3].output_underflow),
                           int(a[2].currentTime * 1e9))
            trace.ncb = i + 1
    out._callback = traced_callback


def report(trace: Trace, late_ms: float, period_ns: int = 1_000_000) -> None:
    ev = trace.ev[:trace.n]
    waits = ev[ev[:, 0] == P["wait"]]
    ru = trace.ru[:trace.nru]
    cb = trace.cb[:trace.ncb]
    gaps = np.diff(cb[:, 0]) if cb.shape[0] > 1 else np.zeros(0, dtype=np.int64)
    flagged = np.flatnonzero(cb[:, 3])
    # how long after PortAudio's own time of the callback (its stream clock, offset calibrated on the earliest one)
    # the Python callback started: the wait for the GIL and for the callback thread's core
    entry = cb[:, 0] - cb[:, 4]
    entry = entry - entry.min()
    print(f"callback entry after PortAudio's time: p50 {np.percentile(entry, 50) / 1e3:.0f} us, p99 "
          f"{np.percentile(entry, 99) / 1e3:.0f} us, max {entry.max() / 1e3:.0f} us; at the underflowing callbacks: "
          f"{(entry[flagged] / 1e3).round().astype(int).tolist()[:12]} us")
    print(f"PortAudio output underflows at callbacks {flagged.tolist()[:20]} (the first loop tick ran at callback "
          f"{int(np.searchsorted(cb[:, 0], waits[0, 1])) if waits.size else None})")
    print(f"{trace.n} phase events, {waits.shape[0]} waits, {cb.shape[0]} callbacks; callback wall p50/p99/max "
          f"{np.percentile(cb[:, 1], 50) / 1e3:.0f}/{np.percentile(cb[:, 1], 99) / 1e3:.0f}/{cb[:, 1].max() / 1e3:.0f} us, "
          f"gap between callbacks p50/max {np.median(gaps) / 1e6:.2f}/{gaps.max() / 1e6:.2f} ms")
    w = trace.waits[:trace.nw]
    slow = np.flatnonzero((w[:, 1] > late_ms * 1e6) | (w[:, 2] > 0))
    print(f"waits that returned more than {late_ms:g} ms late or skipped deadlines: {slow.size} "
          f"(skipped {int(w[:, 2].sum())} deadlines in all)")
    ends = w[:, 0]
    worst = slow[np.lexsort((-w[slow, 1], -w[slow, 2]))][:40]  # most skipped first, then latest
    for j in sorted(worst):
        t_from, t_to = ends[j - 1] - period_ns if j else ends[0] - 2 * period_ns, ends[j]  # the tick before and the wait
        sel = ev[(ev[:, 1] >= t_from) & (ev[:, 1] < t_to)]
        order = np.argsort(-sel[:, 2])[:4]
        phases = ", ".join(f"{PHASES[sel[i, 0]]} {sel[i, 2] / 1e6:.2f} ms (cpu {sel[i, 3] / 1e6:.2f})" for i in order)
        r0 = np.searchsorted(ru[:, 0], t_from)
        r1 = min(np.searchsorted(ru[:, 0], t_to), ru.shape[0] - 1)
        d = ru[r1] - ru[max(r0 - 1, 0)]
        near = cb[(cb[:, 0] >= t_from - 20e6) & (cb[:, 0] < t_to)]
        cbs = (f"{near.shape[0]} callbacks, longest {near[:, 1].max() / 1e3:.0f} us, largest gap "
               f"{np.diff(near[:, 0]).max() / 1e6:.1f} ms" if near.shape[0] > 1 else f"{near.shape[0]} callbacks")
        print(f"  tick {j + 1} at {(ends[j] - ends[0]) / 1e9:7.3f} s: {w[j, 1] / 1e6:6.2f} ms late, {w[j, 2]} skipped; {phases}; "
              f"minflt {d[1]} majflt {d[2]} vol {d[3]} invol {d[4]}; {cbs}")
    tot = {PHASES[c]: ev[ev[:, 0] == c] for c in range(len(PHASES))}
    print("phase totals: " + ", ".join(f"{k} n={v.shape[0]} max {v[:, 2].max() / 1e6:.2f} ms" for k, v in tot.items() if v.shape[0]))


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--rate", type=int, default=8000)
    ap.add_argument("--period", type=int, default=64)
    ap.add_argument("--margin", type=float, default=10.0)
    ap.add_argument("--margin-max", type=float, default=None, help="the map's margin_max_ms (default: the bundled map's)")
    ap.add_argument("--seconds", type=float, default=20.0)
    ap.add_argument("--late-ms", type=float, default=1.0)
    ap.add_argument("--busy", action="store_true", help="one CPU-bound process beside the session")
    ap.add_argument("--rt", action="store_true")
    ap.add_argument("--dump", help="also save the raw trace arrays to this .npz")
    args = ap.parse_args()
    if shutil.which("jackd") is None:
        sys.exit("jackd is not installed (apt-get install jackd2 libportaudio2)")
    name = f"flowtex-trace-{os.getpid()}"
    os.environ.update(JACK_DEFAULT_SERVER=name, JACK_NO_START_SERVER="1")
    trace = Trace()
    install(trace)
    from flowtex.cli import main as cli

    with jack_server(name, args.rate, args.period, realtime=args.rt, busy=args.busy), \
            tempfile.TemporaryDirectory() as tmp:
        m = example_map(Path(tmp), args.rate, args.period, args.margin, args.margin_max)
        stats = Path(tmp) / "stats.json"
        load = os.getloadavg()[0]
        try:
            cli(["live", str(GRAPH), "--bus", "virtual", "--dbc", str(DBC), "--map", str(m), "--simulate", str(REC),
                 "--duration", str(args.seconds), "--stats", str(stats), "--quiet", *(["--rt"] if args.rt else [])])
        except SystemExit:
            pass
        import json

        s = json.loads(stats.read_text())
        a = s["audio"]
        print(f"load {load:.1f}->{os.getloadavg()[0]:.1f}; underruns {a['underruns']} ({a['late_callbacks']} + "
              f"{a['device_underflows']}), resyncs {a['resyncs']}, missed {s['missed']}, latency {a['latency_ms']}")
    report(trace, args.late_ms)
    compiled_live(trace)
    if args.dump:
        np.savez(args.dump, ev=trace.ev[:trace.n], ru=trace.ru[:trace.nru], cb=trace.cb[:trace.ncb], waits=trace.waits[:trace.nw])


def signature_counts() -> dict[str, int]:
    """Compiled signatures per numba function of flowtex's modules (generated graph code included)."""
    from numba.core.registry import CPUDispatcher

    return {f"{name}.{attr}": len(fn.signatures) for name, mod in list(sys.modules.items()) if name.startswith("flowtex")
            for attr, fn in list(vars(mod).items()) if isinstance(fn, CPUDispatcher)}


def compiled_live(trace: Trace) -> None:
    """Numba functions that gained a signature after the clock was built (just before the loop): each was compiled or
    loaded from the cache inside the session, on a first-seen code path or argument type."""
    before = trace.signatures
    grew = [f"{k}: {before.get(k, 0)} -> {n}" for k, n in signature_counts().items() if n > before.get(k, 0)]
    print("numba functions compiled during the session: " + ("; ".join(grew) if grew else "none"))


if __name__ == "__main__":
    main()
    sys.stdout.flush()
    os._exit(0)  # jackd is gone: PortAudio's exit handler would assert in Pa_Terminate
