"""Placing a graph's arena (flowtex.graph.arena.plan_layout), this tree against a baseline tree, side by side.

    python benchmarks/bench_plan_layout.py [--baseline main] [--rounds 3]

Graphs: graphs/hatt_texture.yaml (a usual graph) and a gain on one input of flowtex.limits.MAX_PORT_VALUES values
(the widest graph flowtex loads, tests/io/test_hostile_bounds.py's), both at the default 1,024 rows. CPU seconds
(``time.process_time``) of ``plan_layout`` on the resolved graph, its first call (fresh memory, as
load_graph pays it) and the best of 3 in one process, the processes
alternating between the trees (bench_compile.alternating_json). Each process prints a SHA-256 of the float and int arenas it
placed: the two trees must agree bit for bit (the script exits with an error otherwise).
"""

from __future__ import annotations

import argparse

from bench_compile import alternating_json

WORK = """
import hashlib, json, sys, tempfile, time
from pathlib import Path
from flowtex.graph.arena import plan_layout
from flowtex.graph.compiled import graph_registry
from flowtex.graph.resolve import resolve_graph
from flowtex.graph.spec import load_spec
from flowtex.limits import MAX_PORT_VALUES

wide = Path(tempfile.mkdtemp()) / "wide.yaml"
wide.write_text("flowtex: 1\\nname: wide\\nrate: 1000\\ninputs:\\n  x: {shape: [%d]}\\nnodes:\\n  k: {type: gain, params: {k: 2}}\\n"
                "edges:\\n  - x -> k.x\\noutputs:\\n  y: k.y\\n" % MAX_PORT_VALUES)
out = {}
for name, path in (("hatt_texture.yaml", Path("graphs/hatt_texture.yaml")), ("gain at the port limit", wide)):
    spec = load_spec(path)
    rg = resolve_graph(spec, graph_registry(path, own=spec.plugins))
    times, h = [], hashlib.sha256()
    for _ in range(3):
        t0 = time.process_time()
        lay = plan_layout(rg, 1024)
        times.append(time.process_time() - t0)
        if len(times) < 3:
            del lay
    h.update(lay.f.tobytes()); h.update(lay.i.tobytes())
    out[name] = (times[0], min(times), h.hexdigest())
    del lay
print(json.dumps(out))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--baseline", default="main", help="git revision to compare with (default: main)")
    ap.add_argument("--rounds", type=int, default=3, help="processes per tree")
    args = ap.parse_args()
    got = alternating_json(args.baseline, args.rounds, WORK)
    same = True
    for name in got["baseline"][0]:
        hashes = {r[name][2] for rows in got.values() for r in rows}
        same &= len(hashes) == 1
        for k, what in ((0, "first call"), (1, "best of 3")):
            b, n = (sorted(r[name][k] for r in got[label])[args.rounds // 2] for label in ("baseline", "this"))
            print(f"{name:24s} {what:10s} CPU s (median of {args.rounds}): baseline {b:8.4f}  this {n:8.4f}  "
                  f"ratio {n / b:5.2f}  arenas bit-identical: {len(hashes) == 1}")
    if not same:
        raise SystemExit("the two trees placed different arenas")


if __name__ == "__main__":
    main()
