"""Offline runner: a recording file in, an output file out, through a compiled graph."""

from __future__ import annotations

import shlex
from collections.abc import Mapping
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..dsp.nonfinite import count_nonfinite
from ..errors import DataError, FlowtexError
from ..graph.compiled import Graph, apply_nonfinite_policy
from ..io.formats import format_of
from ..io.recording_rules import check_stated_unit
from ..io.recordings import Recording, load_recording, save_recording

if TYPE_CHECKING:
    from ..graph.resolved import ResolvedGraph
    from ..io.audiomap import AudioMap
    from ..node_api import PortSpec

TIME_COLUMN = "time"
"""A recording signal of this name (unless the graph has such an input) holds sample times in seconds."""
RATE_TOLERANCE = 0.01
"""Relative difference between the rate a ``time`` column implies and the graph's rate that is refused."""


def _check_time_column(time: np.ndarray, name: str, graph_rate: float, input_path: str | Path) -> None:
    """Check the rate implied by a ``time`` column (seconds; median spacing) against the graph's rate."""
    if time.ndim != 1 or time.shape[0] < 2:
        return
    dt = float(np.median(np.diff(time)))
    if not np.isfinite(dt) or dt <= 0:
        raise DataError(f"{input_path}: column 'time' does not increase (median step {dt:g}); "
                        "flowtex reads one row per tick, so fix or drop the time column")
    rate = 1.0 / dt
    if abs(rate - graph_rate) > RATE_TOLERANCE * graph_rate:
        raise DataError(f"{input_path}: column 'time' is spaced {dt:g} s ({rate:g} Hz) but graph {name!r} runs at "
                        f"{graph_rate:g} Hz; resample the recording, set the graph's rate: {rate:g}, "
                        "or drop the time column if it is not in seconds")


def _vector_hint(name: str, shape: tuple[int, ...], have: list[str], path: Path) -> str:
    """A hint when a vector input seems to be stored as columns like ``acc_x, acc_y, acc_z``."""
    if not shape:
        return ""
    width = int(np.prod(shape))
    similar = [h for h in have if h.lower().startswith(name.lower()) and h != name]
    csv = getattr(format_of(path), "name", None) == "csv"
    if not similar and not csv:
        return ""
    cols = ", ".join(f"{name}[{i}]" for i in range(width))
    where = "CSV columns" if csv else "an array of shape (n, " + ", ".join(map(str, shape)) + ")"
    found = f" (not {', '.join(similar)})" if similar else ""
    if csv:
        return f"; input {name!r} has shape ({', '.join(map(str, shape))},): name its {where} {cols}{found}"
    return f"; input {name!r} has shape ({', '.join(map(str, shape))},): store it as one entry {name!r}, {where}{found}"


OUTPUT_POLICIES = ("warn", "error")
"""What ``run_recording`` does with NaN/inf in the graph's outputs: leave it to the caller to warn, or refuse."""


def nonfinite_outputs(outputs: dict[str, np.ndarray]) -> list[str]:
    """One line per output holding NaN or inf: ``output 'y': 3 NaN and 0 inf value(s), the first at tick 17``."""
    lines = []
    for name, values in outputs.items():
        found = count_nonfinite(values) if values.shape[0] else None
        if found is not None:
            lines.append(f"output {name!r}: {found.describe()}")
    return lines


def check_recording_fits(rec: Recording, name: str, graph_rate: float, inputs: Mapping[str, PortSpec],
                         input_path: str | Path) -> None:
    """Refuse a recording whose stated rate or time column is not graph ``name``'s rate (Hz), that lacks one of its
    ``inputs``, or that states a unit for one other than the input's: what needs no compiled graph, so the command line
    checks it before the compile (flowtex run)."""
    if rec.rate is not None and abs(rec.rate - graph_rate) > 1e-9 * graph_rate:
        raise DataError(f"{input_path}: recorded at {rec.rate:g} Hz but graph {name!r} runs at {graph_rate:g} Hz; run "
                        f"'flowtex resample {shlex.quote(str(input_path))} --rate {graph_rate:g} -o OUT.npz' and use OUT.npz, "
                        f"or run the graph at the recording's rate (--set rate={rec.rate:g})")
    if TIME_COLUMN in rec.arrays and TIME_COLUMN not in inputs:
        _check_time_column(rec.arrays[TIME_COLUMN], name, graph_rate, input_path)
    missing = [n for n in inputs if n not in rec.arrays]
    if missing:
        have = ", ".join(rec.arrays) or "nothing"
        hints = "".join(_vector_hint(n, inputs[n].shape, list(rec.arrays), Path(input_path)) for n in missing)
        raise DataError(f"{input_path}: lacks graph input(s) {', '.join(missing)} (the file has: {have}){hints}")
    if not inputs:
        raise FlowtexError(f"graph {name!r} has no inputs; a recording cannot drive it")
    for n, spec in inputs.items():
        check_stated_unit(rec.units, n, spec.unit, input_path, f"graph {name!r} input {n!r}")


def load_recording_for(resolved: ResolvedGraph, input_path: str | Path) -> Recording:
    """The recording at ``input_path``, read and checked against the resolved graph (:func:`check_recording_fits`):
    what the command line reads once the graph is checked and before it is compiled, so that a recording that is
    broken or does not fit is said at once (``load_graph(..., before_compile=...)``)."""
    rec = load_recording(input_path)
    check_recording_fits(rec, resolved.spec.name, resolved.spec.rate, resolved.input_specs, input_path)
    return rec


def run_recording(graph: Graph, input_path: str | Path, output_path: str | Path | None,
                  seed: int | None = None, progress: bool = True, nonfinite: str = "error",
                  nonfinite_out: str = "warn", recording: Recording | None = None) -> dict[str, np.ndarray]:
    """Run ``graph`` over the recording at ``input_path``; write outputs if ``output_path``.

    ``recording`` is that file already read (:func:`flowtex.io.recordings.load_recording`): the command line reads
    it before it compiles the graph, so that a missing or broken recording is said at once, not after the compile.

    A recording that states a sample rate different from the graph's rate is
    refused (resample it first, or fix ``rate:`` in the graph). Non-finite
    samples are handled by ``nonfinite`` (``error``, ``hold`` or ``zero``, as in
    :meth:`Graph.run`); ``error`` names the file, the signal, the count and the first index.
    Non-finite *outputs* (a node that blew up) with ``nonfinite_out="error"`` are refused
    before anything is written; with ``"warn"`` the caller reports :func:`nonfinite_outputs`.
    """
    if nonfinite_out not in OUTPUT_POLICIES:
        raise FlowtexError(f"unknown policy for non-finite outputs {nonfinite_out!r}; use one of {', '.join(OUTPUT_POLICIES)}")
    rec = recording if recording is not None else load_recording(input_path)
    check_recording_fits(rec, graph.name, graph.rate, graph.inputs, input_path)
    arrays = {n: rec.arrays[n] for n in graph.inputs}
    try:
        graph.check_inputs(arrays)
    except FlowtexError as exc:
        raise DataError(f"{input_path}: {exc}") from None
    arrays = apply_nonfinite_policy(arrays, nonfinite, str(input_path),
                                    fix="or pass --nonfinite hold (last finite value) or --nonfinite zero")
    # the policy is applied above; 'pass' hands the NaN/inf on unchanged, so the graph must not refuse them again
    outputs = graph.run(arrays, seed=seed, progress=progress, nonfinite="pass" if nonfinite == "pass" else "error")
    if nonfinite_out == "error":
        bad = nonfinite_outputs(outputs)
        if bad:
            raise DataError(f"graph {graph.name!r} on {input_path}: " + "; ".join(bad) + " (--nonfinite-outputs error: nothing "
                            "written; bound the parameters or inputs that blow up, or use --nonfinite-outputs warn)")
    if output_path is not None:
        save_recording(output_path, outputs, rate=graph.rate, units={n: spec.unit for n, spec in graph.outputs.items()})
    return outputs


AUDIO_RATE_FACTOR = 8
"""Without a map's ``audio`` section, ``--output OUT.wav`` renders at this many times the graph's rate."""


def render_recording_audio(graph: Graph, input_path: str | Path, output_path: str | Path, map_path: str | Path | None = None,
                           seed: int | None = None, progress: bool = True, nonfinite: str = "error",
                           recording: Recording | None = None, nonfinite_out: str = "warn") -> tuple[tuple[int, int], float, list[str]]:
    """Run ``graph`` over a recording and write its audio-rate output as a float32 WAV, block by block (memory of a block
    whatever its length); returns ((frames, channels) written, rate, warnings:
    the outputs holding NaN/inf, which play as silence, then :func:`clip_warnings`). ``nonfinite_out`` as in
    :func:`run_recording` (``"error"``: refused, nothing written).

    The channels, rate, scales and clips come from the ``audio`` section of ``map_path``
    (:mod:`flowtex.io.audiomap`); without a map every scalar output is one channel at
    scale 1, clipped to [-1, 1], at :data:`AUDIO_RATE_FACTOR` times the graph's rate.
    The samples equal what ``flowtex live`` plays for the same outputs, without the live lead of silence.
    """
    from ..io.audiomap import default_audio_map, load_audio_section
    from .audio_render import write_render

    widths = {n: int(np.prod(spec.shape)) for n, spec in graph.outputs.items()}
    if map_path is not None:
        amap = load_audio_section(map_path, widths)
    else:
        amap = default_audio_map(widths, AUDIO_RATE_FACTOR * float(graph.rate))
        if not amap.channels:
            raise FlowtexError(f"graph {graph.name!r} has no scalar output to play; give --map MAP.yaml with an 'audio' section")
    outputs = run_recording(graph, input_path, None, seed=seed, progress=progress, nonfinite=nonfinite, recording=recording,
                            nonfinite_out=nonfinite_out)
    frames = write_render(output_path, outputs, amap, float(graph.rate))
    silent = [f"{line}; played as silence (0), as flowtex live plays them (--nonfinite-outputs error refuses instead)"
              for line in nonfinite_outputs({c.output: outputs[c.output] for c in amap.channels})]
    return (frames, len(amap.channels)), amap.rate, silent + clip_warnings(outputs, amap, float(graph.rate))


def clip_warnings(outputs: dict[str, np.ndarray], amap: AudioMap, graph_rate: float) -> list[str]:
    """One line per audio channel whose clip changed more than CLAMP_WARN_FRACTION of its samples (as live warns of
    clamped CAN outputs): a signal louder than its clip is played distorted, which the WAV alone does not show."""
    from .audio_render import clip_shares
    from .status import CLAMP_WARN_FRACTION

    out = []
    for k, (channel, share) in enumerate(zip(amap.channels, clip_shares(outputs, amap, graph_rate), strict=True)):
        if share > CLAMP_WARN_FRACTION:
            out.append(f"audio channel {k} (output {channel.output!r}): {100 * share:.1f} % of the samples clipped to "
                       f"[{channel.lo:g}, {channel.hi:g}]; lower its level (or give a map whose audio section sets scale "
                       "and clip: docs/live.md)")
    return out
