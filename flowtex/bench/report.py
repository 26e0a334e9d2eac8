"""What ``flowtex bench`` reports (docs/bench.md): the table as CSV, the Pareto plot, and the Dask client it runs on."""

from __future__ import annotations

import contextlib
import csv
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any


@contextlib.contextmanager
def dask_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A Dask client for ``workers`` local processes or a running ``scheduler``, else None (configurations run here)."""
    if not (workers or scheduler):
        yield None
        return
    from dask.distributed import Client, LocalCluster

    if scheduler:
        from ..fit.batch import scheduler_client

        with scheduler_client(scheduler) as client:
            yield client
        return
    with LocalCluster(n_workers=max(1, workers or 1), threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        yield client


NEED_MATPLOTLIB = "plots need matplotlib: pip install 'flowtex[plot]'"


def need_matplotlib() -> None:
    """Raise FlowtexError saying how to install matplotlib when it is missing (before any work)."""
    from ..io.figures import agg_pyplot

    agg_pyplot(NEED_MATPLOTLIB)


def write_csv(path: str | Path, rows: list[list[str]]) -> None:
    """The table as CSV, atomically."""
    from ..io.atomic import atomic_output

    with atomic_output(path) as tmp, open(tmp, "w", newline="") as fh:
        csv.writer(fh).writerows(rows)


def pareto_plot(configs: list, output: str, metric: str, path: Path) -> None:
    """ns/tick against error (:func:`pareto_figure`), written to the PNG ``path``."""
    from ..io.figures import agg_pyplot, save_png

    save_png(pareto_figure(configs, output, metric, agg_pyplot(NEED_MATPLOTLIB)), path, dpi=120)
    print(f"Pareto plot -> {path}", file=sys.stderr)


def pareto_figure(configs: list, output: str, metric: str, plt: Any) -> Any:
    """ns/tick against error, the Pareto front joined; its points numbered 1, 2, ... from the fastest and named in a key
    below the axes (their knob values written beside the points ran into each other and off the figure)."""
    from ..io.figures import FONT_PT

    front = sorted((c for c in configs if c.pareto), key=lambda c: c.ns_per_tick)
    fig, ax = plt.subplots(figsize=(7, 4.5 + 0.2 * len(front)), layout="constrained")
    ax.scatter([c.ns_per_tick for c in configs], [c.errors[output] for c in configs], color="0.6", label="configuration")
    ax.plot([c.ns_per_tick for c in front], [c.errors[output] for c in front], "o-", color="C3", label="Pareto front")
    for k, c in enumerate(front, start=1):
        ax.annotate(str(k), (c.ns_per_tick, c.errors[output]), fontsize=FONT_PT + 1, xytext=(5, 5), textcoords="offset points")
        ax.plot([], [], " ", label=f"{k}: " + ", ".join(f"{name}={v}" for name, v in c.values.items()))
    ax.set_xlabel(f"ns/tick ({configs[0].timed_on})")
    ax.set_ylabel(f"{output} error ({ {'lsd': 'LSD, dB', 'gfc': '1 - GFC'}.get(metric, metric.upper())})")
    ax.grid(alpha=0.3)
    ax.margins(x=0.08, y=0.1)  # room for the numbers beside the points at the ends
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", fontsize=FONT_PT, frameon=False, alignment="left")
    return fig
