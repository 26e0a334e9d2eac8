"""The one entry point of the compile service's subprocesses: ``python -m flowtex.compile.worker JOB REQUEST``.

``JOB`` is ``background`` (compile a graph file's fused tier for next time) or
``prewarm`` (compile the dispatch driver and the listed kernel wrappers);
``REQUEST`` is the JSON the service wrote (:mod:`flowtex.compile.service`).
"""

from __future__ import annotations

import importlib
import json
import sys
from pathlib import Path


def background(request: str) -> int:
    """Compile the fused tier of the graph in ``request``, after stopping an older background job of this cache."""
    from ..cache import cache_dir
    from . import service

    service.lower_priority()
    args = json.loads(request)
    folder = cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    service.take_over(folder / service.PID_FILE)
    from ..graph.compiled import Graph, graph_registry
    from ..graph.resolve import resolve_graph
    from ..graph.spec import parse_spec

    path = Path(args["path"])  # the text as it was; relative paths in it resolve against its folder, as in the run
    spec = parse_spec(args["text"], path, args["overrides"])
    registry = graph_registry(path, tuple(args["plugins"]), args["auto_plugins"], spec.plugins)
    Graph(resolve_graph(spec, registry), args["block_rows"], "fused").prepare("run")  # what the next offline run loads
    return 0


def prewarm(request: str) -> int:
    """Compile the dispatch driver, then each (module, kernel name, inputs, outputs) wrapper of ``request`` in order."""
    from ..graph.dispatch import dispatch_run
    from ..graph.wrappers import load_wrapper

    dispatch_run()  # first: the caller needs the driver last
    for module, name, n_in, n_out in json.loads(request):
        load_wrapper(getattr(importlib.import_module(module), name), n_in, n_out)
    return 0


JOBS = {"background": background, "prewarm": prewarm}


def main(argv: list[str]) -> int:
    job, request = argv
    return JOBS[job](request)


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
