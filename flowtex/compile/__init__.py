"""The compile service: which backend compiles a graph, and the jobs around it (docs/engine.md).

:mod:`.service` chooses the tier, starts the background and prewarm jobs,
reads the environment switches (through :mod:`flowtex.config`) and keeps the
platform guards; :mod:`.worker` is the one entry point of every subprocess it
starts. The backends it drives (:mod:`flowtex.graph.fused`,
:mod:`flowtex.graph.dispatch`) compile in the calling process and start none.
"""
