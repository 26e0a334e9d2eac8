"""Many surfaces: ``flowtex fit texture DIR|GLOB ... --out-dir OUT`` on a Dask cluster (dask.distributed).

Each recording is one task (fit + write ``OUT/<stem>.json``); tasks share
nothing, and the fit is deterministic, so results are identical to a serial
run whatever the worker count. ``--workers N`` starts a local cluster of N
single-threaded worker processes (default: one per core); ``--scheduler
tcp://HOST:8786`` uses a running cluster instead (every worker needs flowtex
installed and read access to the recordings and OUT). ``--workers 0`` fits
serially in this process.
"""

from __future__ import annotations

import glob
import logging
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import DataError, FlowtexError
from ..io.recordings import SUFFIXES


def expand_inputs(items: Sequence[str]) -> list[Path]:
    """Recordings named by files, folders (their recordings, sorted) and glob patterns; duplicates removed."""
    out: list[Path] = []
    if not items:
        raise DataError("give a recording (REC), a folder or a glob pattern to fit")
    for item in items:
        path = Path(item)
        if path.is_dir():
            found = sorted(p for p in path.iterdir() if p.suffix.lower() in SUFFIXES)
        elif any(ch in item for ch in "*?["):
            found = sorted(Path(p) for p in glob.glob(item) if Path(p).suffix.lower() in SUFFIXES)
        else:
            found = [path]
        if not found:
            raise DataError(f"{item}: no recordings ({', '.join(SUFFIXES)}) found")
        seen = {q.resolve() for q in out}  # one file named twice (a.npz, sub/../a.npz, a glob that overlaps) is fitted once
        for p in found:
            if p.resolve() not in seen:
                out.append(p)
                seen.add(p.resolve())
    return out


def check_distinct_outputs(paths: Sequence[Path], out_dir: Path) -> None:
    """Refuse recordings whose surfaces would be written to one file of ``out_dir`` (``OUT/<stem>.json``).

    ``a/rec.npz`` and ``b/rec.npz`` (or ``rec.npz`` and ``rec.csv``) both went to ``OUT/rec.json``: the second fit
    replaced the first, and the summary still counted two surfaces.
    """
    first: dict[str, Path] = {}
    for p in paths:
        other = first.setdefault(p.stem, p)
        if other is not p:
            raise DataError(f"--out-dir {out_dir}: {other} and {p} would both be written to {out_dir / (p.stem + '.json')}; "
                            "rename one, or fit them into separate --out-dir folders")


def fit_one(path: str, job, out_dir: str, xml: bool, report_dir: str | None) -> tuple[str, str]:
    """Fit one recording and write its outputs (and, with ``report_dir``, its report into ``report_dir/<stem>_report``);
    returns (recording, one-line summary or 'error: ...')."""
    from .report import edge_warning, summary_line, write_report
    from .texture_job import fit_recording, write_outputs

    p = Path(path)
    out = Path(out_dir) / f"{p.stem}.json"
    try:
        fit = fit_recording(p, job)
        written = write_outputs(fit, out, out.with_suffix(".xml") if xml else None, job.render_rate, job.allow_misses)
        if report_dir is not None:
            write_report(fit, Path(report_dir) / f"{p.stem}_report", written=written)
        warning = edge_warning(fit)
        return path, summary_line(fit) + (f"; warning: {warning}" if warning else "")
    except FlowtexError as exc:
        return path, f"error: {exc}"


def scheduler_client(address: str) -> Any:
    """A Dask ``Client`` connected to the running scheduler at ``address``; FlowtexError naming it if none answers."""
    from dask.distributed import Client

    try:
        return Client(address)
    except (OSError, TimeoutError, ValueError) as exc:
        raise FlowtexError(f"--scheduler {address}: cannot reach the Dask scheduler ({' '.join(str(exc).split())[:200]}); "
                           "start it (dask scheduler) or check the address") from None


def fit_many(paths: Sequence[Path], job, out_dir: Path, workers: int | None, scheduler: str | None, xml: bool = False,
             report_dir: Path | None = None) -> int:
    """Fit every recording (serially, on a local cluster or on ``scheduler``) into ``out_dir``, each report (with
    ``report_dir``) into ``report_dir/<stem>_report``; returns the exit code (1 if any failed)."""
    from tqdm import tqdm

    check_distinct_outputs(paths, out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    report = None if report_dir is None else str(report_dir)
    show = sys.stderr.isatty()
    results: dict[str, str] = {}
    if scheduler is None and workers == 0:
        for p in tqdm(paths, disable=not show, unit="surface"):
            k, line = fit_one(str(p), job, str(out_dir), xml, report)
            results[k] = line
    else:
        from dask.distributed import Client, LocalCluster, as_completed

        cluster = None
        if scheduler is None:
            cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1, processes=True,
                                   dashboard_address=None, silence_logs=logging.ERROR)
        try:
            with (scheduler_client(scheduler) if scheduler is not None else Client(cluster)) as client:
                futures = [client.submit(fit_one, str(p), job, str(out_dir), xml, report, pure=False) for p in paths]
                for fut in tqdm(as_completed(futures), total=len(futures), disable=not show, unit="surface"):
                    k, line = fut.result()
                    results[k] = line
        except OSError as exc:
            raise FlowtexError(f"cannot reach the Dask scheduler {scheduler}: {exc}") from None
        finally:
            if cluster is not None:
                cluster.close()
    failed = 0
    for p in paths:
        line = results[str(p)]
        failed += line.startswith("error:")
        print(f"{p}: {line}")
    print(f"{len(paths) - failed} of {len(paths)} surfaces -> {out_dir}")
    return 1 if failed else 0
