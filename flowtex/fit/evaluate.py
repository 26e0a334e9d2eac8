"""How faithful a surface is, from files: ``flowtex compare`` and ``fit texture --holdout`` (logic only, no argparse).

:func:`compare_files` reads a model set and a recording and runs
flowtex.fit.compare.compare_surface; :func:`fit_holdout` fits a texture on
all but a held-out ``fraction`` of a recording (its end, or interleaved
one-second blocks: flowtex.fit.crossval) and compares it there, where the fit
never looked.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .compare import CompareOptions, Comparison, compare_surface
from .texture import TextureFit, TextureOptions
from .texture_job import TextureJob, read_signals


def compare_files(surface: Path, recording: Path, job: TextureJob, opt: CompareOptions | None = None) -> Comparison:
    """Render the model set in ``surface`` along ``recording``'s speed and force (signals named by ``job``) and compare."""
    from ..io.modelset import load_model_set

    ms = load_model_set(surface)
    acc, speed, force, rate = read_signals(recording, job)
    assert speed is not None and force is not None
    return compare_surface(ms, acc, speed, force, rate, opt, str(recording))


def fit_holdout(acc: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float, fraction: float,
                opt: TextureOptions | None = None, material: str = "surface", where: str = "recording",
                compare: CompareOptions | None = None, split: str = "tail") -> tuple[TextureFit, Comparison]:
    """Fit on all but the held-out ``fraction`` (the last part, or interleaved one-second blocks: flowtex.fit.crossval), compare there."""
    from .crossval import evaluate_splits, holdout_split

    cv = evaluate_splits(acc, speed, force, rate, [holdout_split(acc.shape[0], rate, fraction, split, where)], opt,
                         material, where, compare)
    return cv.fits[0], cv.comparisons[0]
