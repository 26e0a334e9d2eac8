"""How faithful a surface is, from files: ``flowtex compare`` and ``fit texture --holdout`` (logic only, no argparse).

:func:`compare_files` reads a model set and a recording and runs
flowtex.fit.compare.compare_surface; :func:`fit_holdout` fits a texture on the
first ``1 - fraction`` of a recording and compares it with the last
``fraction``, which the fit never saw.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import DataError
from .compare import CompareOptions, Comparison, compare_surface
from .texture import TextureFit, TextureOptions, fit_texture
from .texture_job import TextureJob, read_signals

MIN_HOLDOUT_S = 2.0
"""Shortest held-out part (s): the comparison skips 0.5 s and correlates 1-s windows."""


def compare_files(surface: Path, recording: Path, job: TextureJob, opt: CompareOptions | None = None) -> Comparison:
    """Render the model set in ``surface`` along ``recording``'s speed and force (signals named by ``job``) and compare."""
    from ..io.modelset import load_model_set

    ms = load_model_set(surface)
    acc, speed, force, rate = read_signals(recording, job)
    assert speed is not None and force is not None
    return compare_surface(ms, acc, speed, force, rate, opt, str(recording))


def split_holdout(n: int, rate: float, fraction: float, where: str) -> int:
    """The first held-out sample when the last ``fraction`` of ``n`` samples is held out; DataError if either part is too short."""
    if not (np.isfinite(fraction) and 0.0 < fraction < 1.0):
        raise DataError(f"--holdout must be a fraction between 0 and 1 (e.g. 0.25), got {fraction!r}")
    cut = int(round(n * (1.0 - fraction)))
    if cut / rate < MIN_HOLDOUT_S:
        raise DataError(f"{where}: --holdout {fraction:g} leaves {cut / rate:.2f} s to fit, fewer than {MIN_HOLDOUT_S:g} s; "
                        f"hold out at most {1 - MIN_HOLDOUT_S * rate / n:.2f} of this {n / rate:.1f}-s recording")
    held = (n - cut) / rate
    if held < MIN_HOLDOUT_S:
        raise DataError(f"{where}: --holdout {fraction:g} holds out {held:.2f} s, fewer than {MIN_HOLDOUT_S:g} s to compare; "
                        f"hold out at least {MIN_HOLDOUT_S * rate / n:.2f} of this {n / rate:.1f}-s recording")
    return cut


def fit_holdout(acc: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float, fraction: float,
                opt: TextureOptions | None = None, material: str = "surface", where: str = "recording",
                compare: CompareOptions | None = None) -> tuple[TextureFit, Comparison]:
    """Fit on the first ``1 - fraction`` of the recording, compare the fit with the last ``fraction`` (module docstring)."""
    cut = split_holdout(acc.shape[0], rate, fraction, where)
    fit = fit_texture(acc[:cut], speed[:cut], force[:cut], rate, opt, material, where)
    cmp = compare_surface(fit.model_set, acc[cut:], speed[cut:], force[cut:], rate, compare, f"{where} (held-out part)")
    return fit, cmp
