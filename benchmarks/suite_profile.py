"""Where the test suite's time goes, from the logs of tests/suite_profile.py (docs/testing.md).

    PYTEST_FLOWTEX_PROFILE=/tmp/prof python3 -m pytest -q -n auto --dist loadfile
    python3 benchmarks/suite_profile.py /tmp/prof [--top 40] [--tests 30]

Prints, per test file (heaviest first): wall time, CPU time of the pytest worker and of the subprocesses it
waited for, and wall time inside numba (compiles and cache loads; real compiles alone); then the same per
worker, which shows how evenly ``--dist`` spread the work; then the functions numba compiled more than once;
with ``--tests N``, the N heaviest tests (their CPU and their subprocesses' CPU) last.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

KEYS = ("wall", "cpu", "children", "numba", "compiles")


def load(folder: Path) -> list[dict]:
    """Every test's record in ``folder``'s ``*.jsonl`` files."""
    return [json.loads(line) for path in sorted(folder.glob("*.jsonl")) for line in path.read_text().splitlines() if line]


def totals(rows: list[dict], by: str) -> dict[str, dict[str, float]]:
    """Sums of :data:`KEYS` (and the test count ``n``) grouped by the record field ``by``."""
    out: dict[str, dict[str, float]] = defaultdict(lambda: dict.fromkeys((*KEYS, "n"), 0.0))
    for r in rows:
        for k in KEYS:
            out[r[by]][k] += r[k]
        out[r[by]]["n"] += 1
    return dict(out)


def table(groups: dict[str, dict[str, float]], top: int) -> str:
    lines = [f"{'':60s} {'tests':>5s} {'wall s':>8s} {'cpu s':>8s} {'child s':>8s} {'numba s':>8s} {'compile s':>9s}"]
    ranked = sorted(groups.items(), key=lambda kv: -(kv[1]["cpu"] + kv[1]["children"]))
    for name, t in ranked[:top]:
        lines.append(f"{name[-60:]:60s} {int(t['n']):5d} {t['wall']:8.1f} {t['cpu']:8.1f} {t['children']:8.1f} {t['numba']:8.1f} "
                     f"{t['compiles']:9.1f}")
    all_ = {k: sum(t[k] for t in groups.values()) for k in (*KEYS, "n")}
    lines.append(f"{'total':60s} {int(all_['n']):5d} {all_['wall']:8.1f} {all_['cpu']:8.1f} {all_['children']:8.1f} "
                 f"{all_['numba']:8.1f} {all_['compiles']:9.1f}")
    return "\n".join(lines)


def compiled_twice(rows: list[dict]) -> dict[str, list[str]]:
    """Functions (with signature) that numba compiled in more than one worker: work the shared disk cache did not save."""
    where: dict[str, set[str]] = defaultdict(set)
    for r in rows:
        for name in r.get("compiled", ()):
            where[name].add(r["worker"])
    return {name: sorted(workers) for name, workers in where.items() if len(workers) > 1}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("folder", type=Path)
    ap.add_argument("--top", type=int, default=40)
    ap.add_argument("--tests", type=int, default=0, help="also list the N heaviest tests")
    args = ap.parse_args()
    rows = load(args.folder)
    print(table(totals(rows, "file"), args.top))
    print()
    print(table(totals(rows, "worker"), args.top))
    twice = compiled_twice(rows)
    total = sum(len(r.get("compiled", ())) for r in rows)
    print(f"\n{total} numba compiles; {len(twice)} functions compiled in more than one worker:")
    for name, workers in sorted(twice.items())[:args.top]:
        print(f"  {name[:140]}  {' '.join(workers)}")
    if args.tests:
        print()
        print(table({r["test"]: {**{k: r[k] for k in KEYS}, "n": 1} for r in rows}, args.tests))


if __name__ == "__main__":
    main()
