"""Replay of a live session log: the streamed replay (flowtex.runtime.replay) vs the whole-list one it replaced.

The whole-list replay (tests/runtime/replay_whole_list.py, the code before the replay streamed) reads every frame
into a list, splits it into ticks, then replays; the streamed one replays a tick as the next block is read. Both run
side by side in this process over the same logs (tests/runtime/long_session.py: a stateless two-gain graph, four
frames a tick, every tick equal to live), alternating, best of ``--rounds``: time per tick, and tracemalloc's peak
(a run of its own, as tracemalloc slows Python) for N and 4N ticks.

    python benchmarks/bench_replay.py [--ticks 20000] [--rounds 3] [--formats .blf .log .asc]
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "runtime")]  # this tree's flowtex, and the tests' session writer and oracle
from long_session import FRAMES_PER_TICK, LongSession, peak_bytes  # noqa: E402
from replay_whole_list import replay_whole_list  # noqa: E402

from flowtex.graph.compiled import load_graph  # noqa: E402
from flowtex.runtime.replay import replay_session  # noqa: E402

REPLAYS = {"whole list": replay_whole_list, "streamed": replay_session}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--ticks", type=int, default=20000)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--formats", nargs="+", default=[".blf", ".log", ".asc"])
    args = ap.parse_args()
    folder = Path(tempfile.mkdtemp(prefix="bench_replay"))
    session = LongSession(folder)
    graph = load_graph(session.graph)
    n = args.ticks
    print(f"N = {n} ticks ({n * FRAMES_PER_TICK} frames; peaks also at 4N); time: best of {args.rounds}")
    for suffix in args.formats:
        logs = {ticks: session.write(folder / f"s{ticks}{suffix}", ticks) for ticks in (n, 4 * n)}

        def run(fn, ticks, logs=logs):
            rep = fn(graph, logs[ticks], session.dbc, session.map, seed=3)
            assert rep.identical and rep.ticks == ticks

        best = dict.fromkeys(REPLAYS, float("inf"))
        run(replay_session, n)  # warm: the map's codecs, the file in the page cache
        for _ in range(args.rounds):
            for name, fn in REPLAYS.items():
                t0 = time.perf_counter()
                run(fn, n)
                best[name] = min(best[name], time.perf_counter() - t0)
        peaks = {name: [peak_bytes(lambda fn=fn, t=t: run(fn, t)) for t in (n, 4 * n)] for name, fn in REPLAYS.items()}
        size = logs[n].stat().st_size / 2**20
        print(f"{suffix} ({size:.1f} MiB for {n} ticks)")
        for name in REPLAYS:
            per_tick = best[name] / n * 1e6
            a, b = (p / 2**20 for p in peaks[name])
            print(f"  {name:10s} {per_tick:7.1f} us a tick ({best[name]:.2f} s)   peak {a:7.2f} MiB at N, {b:7.2f} MiB at 4N")
        print(f"  streamed / whole list: time {best['streamed'] / best['whole list']:.2f}, "
              f"peak at 4N {peaks['streamed'][1] / peaks['whole list'][1]:.3f}")


if __name__ == "__main__":
    main()
