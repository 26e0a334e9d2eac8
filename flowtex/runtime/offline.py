"""Offline runner: a recording file in, an output file out, through a compiled graph."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError, FlowtexError
from ..graph.compiled import Graph, apply_nonfinite_policy
from ..io.recordings import load_recording, save_recording


def run_recording(graph: Graph, input_path: str | Path, output_path: str | Path | None,
                  seed: int | None = None, progress: bool = True, nonfinite: str = "error") -> dict[str, np.ndarray]:
    """Run ``graph`` over the recording at ``input_path``; write outputs if ``output_path``.

    A recording that states a sample rate different from the graph's rate is
    refused (resample it first, or fix ``rate:`` in the graph). Non-finite
    samples are handled by ``nonfinite`` (``error``, ``hold`` or ``zero``, as in
    :meth:`Graph.run`); ``error`` names the file, the signal, the count and the first index.
    """
    rec = load_recording(input_path)
    if rec.rate is not None and abs(rec.rate - graph.rate) > 1e-9 * graph.rate:
        raise DataError(f"{input_path}: recorded at {rec.rate:g} Hz but graph {graph.name!r} runs at {graph.rate:g} Hz; "
                        "resample the recording or change the graph's rate")
    missing = [n for n in graph.inputs if n not in rec.arrays]
    if missing:
        have = ", ".join(rec.arrays) or "nothing"
        raise DataError(f"{input_path}: lacks graph input(s) {', '.join(missing)} (the file has: {have})")
    if not graph.inputs:
        raise FlowtexError(f"graph {graph.name!r} has no inputs; a recording cannot drive it")
    arrays = apply_nonfinite_policy({n: rec.arrays[n] for n in graph.inputs}, nonfinite, str(input_path),
                                    fix="or pass --nonfinite hold (last finite value) or --nonfinite zero")
    outputs = graph.run(arrays, seed=seed, progress=progress, nonfinite="error")
    if output_path is not None:
        save_recording(output_path, outputs, rate=graph.rate)
    return outputs
