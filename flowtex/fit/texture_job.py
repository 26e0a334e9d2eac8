"""A texture fit job: recordings of free exploration (or a Romano-2012 grid) -> a texture model set, written.

What ``flowtex fit texture`` (flowtex/cli/fit_texture.py) runs for one recording, a grid index or
(flowtex.fit.batch) many recordings. The pipeline is flowtex.fit.texture; docs/fitting.md describes every option.
"""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..io.formats import TEXT_ENCODING
from ..limits import check_file_size
from ..models.texture import TextureModelSet
from .inputs import atomic_output, check_highpass, check_not_constant, check_speed_magnitude, load, signal, signals_listed
from .texture import TextureFit, TextureOptions, fit_grid, fit_texture


@dataclass
class TextureJob:
    """Everything one texture fit needs besides the recording: signal names and options (picklable for Dask)."""

    accel: str = "accel"
    speed: str | None = None
    force: str = "normal_force"
    position: str | None = None
    normal: str | None = None
    rate: float | None = None
    options: TextureOptions | None = None
    render_rate: float | None = None
    material: str | None = None
    allow_misses: bool = False


def speed_from_position(position: np.ndarray, normal: np.ndarray | None, rate: float) -> np.ndarray:
    """Tangential speed (mm/s) from position (mm): the speed_estimator node itself (hatt method, its stationary gate),
    run on the arrays through ``Node.processor``; no normal means the node's default normal, +z."""
    from ..nodes.motion import SpeedEstimator

    proc = SpeedEstimator.processor(rate=rate, method="hatt")
    inputs = {"position": position} if normal is None else {"position": position, "normal": normal}
    return proc(**inputs)["speed"][:, 0]


def read_signals(path: Path, job: TextureJob, need_speed: bool = True) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, float]:
    """(1-D acceleration, speed, force, rate) of one recording, checked (see flowtex.fit.inputs).

    Grid cells (``need_speed=False``) need only the acceleration: speed and force come from the index.
    """
    rec, rate = load(path, job.rate)
    if job.options is not None:
        check_highpass(job.options.highpass_hz, rate)
    if job.render_rate is not None:
        from .resample import check_rate_ratio

        check_rate_ratio(rate, job.render_rate, "--render-rate", "recording")
    acc = signal(rec, job.accel, "--accel", (1, 3))
    if acc.ndim == 2:
        from ..dsp.dft321 import dft321

        acc = dft321(acc)
    check_not_constant(acc, f"{path}: signal {job.accel!r} (--accel)")
    if not need_speed:
        return acc, None, None, rate
    force = signal(rec, job.force, "--force")
    speed = None
    if job.speed is not None:
        speed = signal(rec, job.speed, "--speed")
        check_speed_magnitude(speed, f"{rec.path}: signal {job.speed!r} (--speed)")
    elif job.position is not None:
        pos = signal(rec, job.position, "--position", (3,))
        nrm = signal(rec, job.normal, "--normal", (3,)) if job.normal is not None else None
        speed = speed_from_position(pos, nrm, rate)
    else:
        raise DataError(f"{path}: give the tool's speed with --speed S (mm/s) or --position P (mm, 3 axes); {signals_listed(rec)}")
    return acc, speed, force, rate


def fit_recording(path: Path, job: TextureJob) -> TextureFit:
    """Fit one free-exploration recording."""
    acc, speed, force, rate = read_signals(path, job)
    assert speed is not None and force is not None
    material = job.material or path.stem
    return fit_texture(acc, speed, force, rate, job.options, material, str(path))


def fit_grid_index(index: Path, job: TextureJob) -> TextureFit:
    """Fit a grid: ``index`` is a CSV with columns file, speed (mm/s), force (N); files relative to it."""
    check_file_size(index, "grid index")
    try:
        with index.open(newline="", encoding=TEXT_ENCODING) as fh:
            reader = csv.DictReader(fh)
            rows = [(reader.line_num, row) for row in reader]
    except OSError as exc:
        raise DataError(f"{index}: cannot read the grid index ({exc.strerror or exc})") from None
    except UnicodeDecodeError as exc:
        raise DataError(f"{index}: not UTF-8 text at byte {exc.start}; a grid index is a CSV file") from None
    except csv.Error as exc:  # a NUL byte, a quote left open
        raise DataError(f"{index}: not a readable CSV file ({exc})") from None
    if not rows or not {"file", "speed", "force"} <= set(rows[0][1]):
        raise DataError(f"{index}: a grid index needs a header row with columns file, speed, force and one row per recording")
    cells = []
    rate = None
    for k, row in rows:
        try:
            s, f = float(row["speed"]), float(row["force"])
        except (TypeError, ValueError):
            raise DataError(f"{index}:{k}: speed and force must be numbers (mm/s, N)") from None
        if not (math.isfinite(s) and math.isfinite(f) and s >= 0 and f >= 0):
            raise DataError(f"{index}:{k}: speed {row['speed']} and force {row['force']} must be finite and >= 0 (mm/s, N)")
        if not row["file"]:
            raise DataError(f"{index}:{k}: no file named in the 'file' column")
        acc, _speed, _force, r = read_signals(index.parent / row["file"], job, need_speed=False)
        if rate is not None and r != rate:
            raise DataError(f"{index}:{k}: {row['file']} is at {r:g} Hz but the others are at {rate:g} Hz")
        rate = r
        cells.append((acc, s, f))
    assert rate is not None
    return fit_grid(cells, rate, job.options, job.material or index.stem, str(index))


def write_outputs(fit: TextureFit, output: Path, xml: Path | None, render_rate: float | None,
                  allow_misses: bool = False) -> TextureModelSet:
    """Write the native set (and HaTT XML) atomically, after resampling to ``render_rate`` if given; returns the set
    written.

    A resampled set with models that miss their spectrum is refused (FlowtexError naming them) unless ``allow_misses``.
    """
    from ..io.hatt import write_hatt_xml
    from ..io.modelset import save_model_set

    ms = fit.model_set
    if render_rate is not None and render_rate != ms.sample_rate:
        ms = _resample(ms, render_rate, allow_misses, str(output))
    with atomic_output(output) as tmp:
        save_model_set(ms, tmp)
        if xml is not None:
            with atomic_output(xml) as tmp_xml:
                write_hatt_xml(ms, tmp_xml)
    return ms


def _resample(ms: Any, rate: float, allow_misses: bool, where: str) -> Any:
    """The set at ``rate`` Hz by flowtex models resample's method and default (``--densify auto``: models added where
    the resampled set would otherwise depart from the fitted one along a path), with a one-line account of what it cost."""
    from .resample import check_misses, tqdm_progress
    from .resample_densify import densify_summary, resample_densified

    progress, close = tqdm_progress(ms.num_models, "resample")
    try:
        dense, out = resample_densified(ms, rate, progress=progress, option="--render-rate")
    finally:
        close()
    added = densify_summary(where, ms, dense)
    if added:
        print(added)
    warning = check_misses(out, allow_misses, where)
    info = out.metadata["resample"]
    print(f"resampled {info['from_hz']:g} Hz -> {info['to_hz']:g} Hz: orders {ms.ar_order}/{ms.ma_order} -> "
          f"{out.ar_order}/{out.ma_order}, worst LSD {info['worst_lsd_db']:.2f} dB, "
          f"worst band-power error {100 * info['worst_band_power_error']:.2f} %")
    if warning:
        print(warning)
    return out


def parse_order(text: str) -> tuple[int, int] | None:
    if text == "auto":
        return None
    try:
        p, q = (int(v) for v in text.split(","))
    except ValueError:
        raise DataError(f"--order must be auto or P,Q (e.g. 10,8), got {text!r}") from None
    if p < 1 or q < 0:
        raise DataError(f"--order {text}: the AR order must be >= 1 and the MA order >= 0")
    return p, q
