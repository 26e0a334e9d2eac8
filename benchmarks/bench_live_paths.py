"""The live runtime's second paths against their first, side by side in this process: do they pay?

    python benchmarks/bench_live_paths.py [--ticks 20000] [--sleepy 3000]

The live runtime keeps two ways of doing two things (docs/live.md, "How steps 3 and 5 stay small"):

- ``tick``: one live tick's compute (decode the tick's sensor frames, one graph tick,
  watchdog, output guard, encode every actuator frame) as the fused compiled call
  (:mod:`flowtex.runtime.fused`) against the general steps one by one (compiled decode,
  ``step_block``, ``Watchdog.check``, ``CanIO.guard_and_encode``), which maps without a
  compiled output call use. Both are :func:`flowtex.runtime.tick.tick_compute`, each on
  its own copy of graph, map and watchdog fed the same frames; their actuator bytes are
  compared every tick.
- ``codec``: decoding one tick's sensor frames and encoding its actuator frames with the
  generated Python codecs (:meth:`CanIO.decode`, ``CanIO.encoders``) against the compiled
  table codecs (:func:`~flowtex.io.codec_tables.decode_packed`, :class:`~flowtex.io.codec_tables.TableEncoder`
  plus the copies into the frames); values and bytes are compared.

Graph: graphs/live_texture.yaml on graphs/data/exploration.npz with the example device
(graphs/devices/example.dbc + example_map.yaml); the frames are those the simulated device
sends for each sample. Each comparison runs twice: back to back (hot caches), and one tick
after a 0.8 ms sleep as in the live loop at 1 kHz (cold caches; the two ways alternate tick
by tick so both see the same machine). Reported: p50 and p99 ns per tick of each way and the
ratio second / first. The machine's load average is printed: on a shared machine compare
ratios, not absolute figures.
"""

from __future__ import annotations

import argparse
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import numpy as np

from flowtex.graph.compiled import load_graph
from flowtex.io.codec_tables import decode_packed
from flowtex.runtime.buses import receiver
from flowtex.runtime.canio import CanIO, load_io, tick_out
from flowtex.runtime.fused import fuse_tick
from flowtex.runtime.realtime import freeze_gc
from flowtex.runtime.simdevice import in_process_device
from flowtex.runtime.tick import rx_decoder, tick_compute

REPO = Path(__file__).resolve().parents[1]
GRAPH = REPO / "graphs" / "live_texture.yaml"
RECORDING = REPO / "graphs" / "data" / "exploration.npz"
DBC = REPO / "graphs" / "devices" / "example.dbc"
MAP = REPO / "graphs" / "devices" / "example_map.yaml"
SLEEP_S = 0.0008


def sensor_frames(io: CanIO, rate: float, n: int) -> list[list[can.Message]]:
    """The frames the simulated device sends for samples 0..n-1 of the recording, one list per tick."""
    bus, dev_bus, device = in_process_device(None, io.map, io.codecs, RECORDING, rate)
    receive = receiver(bus)
    ticks: list[list[can.Message]] = []
    try:
        for k in range(n):
            device.publish(k)
            got: list[Any] = []
            receive(got)
            ticks.append([can.Message(arbitration_id=m.arbitration_id, is_extended_id=m.is_extended_id, data=bytearray(m.data),
                                       timestamp=m.timestamp) for m in got])
    finally:
        bus.shutdown()
        dev_bus.shutdown()
    return ticks


def session() -> tuple[Any, CanIO, Any]:
    """A fresh one-row graph, its CanIO and a watchdog whose overrun limit no test machine reaches."""
    g = load_graph(GRAPH).with_block_rows(1)
    io = load_io(g, DBC, MAP)
    return g, io, io.new_watchdog(1 << 62, emit_log=False)


def tick_paths() -> tuple[dict[str, Callable[[list[Any], int], Any]], dict[str, CanIO]]:
    """``tick``: the fused compute and the separate one, each on its own graph, map and watchdog."""
    calls, ios = {}, {}
    for name in ("separate", "fused"):
        g, io, wd = session()
        g.warm()
        fused = fuse_tick(g, io, tick_out, wd.last) if name == "fused" else None
        assert name == "separate" or fused is not None, "the example map must take the fused path"
        compute = tick_compute(g, io, wd, fused, rx_decoder(io, wd))
        calls[name] = (lambda c: lambda rx, k: c(rx, k, 0))(compute)
        ios[name] = io
    return calls, ios


def codec_paths() -> tuple[dict[str, Callable[[list[Any], int], Any]], dict[str, CanIO]]:
    """``codec``: one tick's decode + encode with the Python codecs and with the compiled tables."""
    calls, ios = {}, {}
    g, io, wd = session()
    encoders = list(zip(io.encoders, [m.data for m in io.tx], strict=True))
    decode = io.decode

    def python(rx: list[Any], k: int) -> None:
        for msg in rx:
            decode(msg, k, wd)
        for enc, data in encoders:
            enc(data)

    calls["python"], ios["python"] = python, io
    g2, io2, wd2 = session()
    codec = io2.codec
    td, te = codec.decoder, codec.encoder
    assert td is not None and te is not None and not codec.python_frames, "the example map must be all compiled messages"
    decode_rx = rx_decoder(io2, wd2)
    words, arena, last, out, frames = td.words, codec.arena, wd2.last, io2.out, codec.fast_frames

    def compiled(rx: list[Any], k: int) -> None:
        mask = decode_rx(rx, k, words)
        if mask:
            decode_packed(td.ibuf, td.fbuf, mask, k, arena, last)
        te.run(out)
        for data, src in frames:
            data[:] = src

    calls["compiled"], ios["compiled"] = compiled, io2
    # both encode the same guarded values: give each map the same outputs to encode
    rng = np.random.default_rng(1)
    values = rng.uniform(-0.5, 0.5, io.out.shape[0])
    io.out[:] = values
    io2.out[:] = values
    return calls, ios


def measure(calls: dict[str, Callable[[list[Any], int], Any]], ios: dict[str, CanIO], frames: list[list[can.Message]],
            ticks: int, sleepy: int) -> dict[str, Any]:
    """Per-tick ns of each way: back to back (blocks of 1000 ticks, alternating), then after a sleep (alternating ticks)."""
    names = list(calls)
    n = len(frames)
    hot = {name: [] for name in names}
    cold = {name: [] for name in names}
    now = time.perf_counter_ns
    identical = True
    k = 0
    with freeze_gc():
        for name in names:  # compile/warm, and check both ways send the same bytes on the same frames
            for j in range(200):
                calls[name](frames[j % n], j)
        for j in range(200, 200 + min(n, 2000)):
            for name in names:
                calls[name](frames[j % n], j)
            sent = [[bytes(m.data) for m in ios[name].tx] for name in names]
            identical = identical and all(s == sent[0] for s in sent)
        k = 200 + min(n, 2000)
        for _ in range(max(1, ticks // 1000)):
            for name in names:  # every way runs the same 1000 ticks (its own graph and map: each sees ticks in order)
                call, times = calls[name], hot[name]
                for j in range(k, k + 1000):
                    rx = frames[j % n]
                    t0 = now()
                    call(rx, j)
                    times.append(now() - t0)
            k += 1000
        for _ in range(sleepy):
            for name in names:
                rx = frames[k % n]
                time.sleep(SLEEP_S)
                t0 = now()
                calls[name](rx, k)
                cold[name].append(now() - t0)
            k += 1
    out: dict[str, Any] = {"identical": identical}
    for label, data in (("hot", hot), ("after sleep", cold)):
        out[label] = {name: (float(np.percentile(v, 50)), float(np.percentile(v, 99))) for name, v in data.items() if v}
    return out


def report(title: str, first: str, second: str, res: dict[str, Any]) -> None:
    print(f"{title}: {second} against {first}  (bytes identical: {res['identical']})")
    for label in ("hot", "after sleep"):
        a, b = res[label][first], res[label][second]
        print(f"  {label:12s} {first:9s} p50 {a[0]:8.0f} ns  p99 {a[1]:8.0f} ns | {second:9s} p50 {b[0]:8.0f} ns  p99 {b[1]:8.0f} ns"
              f" | ratio p50 {b[0] / a[0]:5.2f}  p99 {b[1] / a[1]:5.2f}")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--ticks", type=int, default=20_000, help="back-to-back ticks per way")
    ap.add_argument("--sleepy", type=int, default=3_000, help="ticks per way after a 0.8 ms sleep")
    args = ap.parse_args()
    load_before = os.getloadavg() if hasattr(os, "getloadavg") else None
    g, io, _ = session()
    frames = sensor_frames(io, float(g.rate), 4000)
    print(f"{GRAPH.relative_to(REPO)} on {RECORDING.relative_to(REPO)}, {sum(map(len, frames)) / len(frames):.1f} sensor frames "
          f"and {len(io.tx)} actuator frames per tick; load average before {load_before}")
    calls, ios = tick_paths()
    report("tick", "separate", "fused", measure(calls, ios, frames, args.ticks, args.sleepy))
    calls, ios = codec_paths()
    report("codec", "python", "compiled", measure(calls, ios, frames, args.ticks, args.sleepy))
    print(f"load average after {os.getloadavg() if hasattr(os, 'getloadavg') else None}")


if __name__ == "__main__":
    main()
