"""Held-out figures a researcher can trust: a tail hold-out, interleaved one-second blocks, K-fold cross-validation.

Real recordings change loudness from one second to the next by 1.5-5.7 dB
(standard deviation) at the same speed and force, and drift over time, so a
tail hold-out (the last FRACTION) measures the drift as much as the surface.
Interleaved one-second blocks spread the held-out data over the whole
recording; K folds (block k is held out by fold k mod K) use every second
once, and the mean over the folds measures the surface, not one split.

No splice is ever made: the fit high-passes the whole recording and takes its
pieces inside the training blocks only (``fit_texture(within=...)``, so no
filter transient appears at a block edge and no piece straddles two blocks),
and the comparison renders the surface along the whole recorded path and
measures only the held-out blocks (``compare_surface(ranges=...)``). The
zero-phase 10 Hz high-pass reaches about 0.1 s across a block edge, so
below 10 Hz a held-out second touches the fit's data; the fit's 0.05 s trims
at every piece end keep that out of the models above 10 Hz.

Units: samples, seconds (``rate`` Hz).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from ..errors import DataError
from .compare import CompareOptions, Comparison, compare_highpassed, highpassed, surface_renders
from .texture import TextureFit, TextureOptions, fit_texture

BLOCK_S = 1.0
"""Length (s) of the interleaved blocks."""
MIN_HELD_S = 2.0
"""Shortest held-out part (s) of a split."""
CV_WINDOW_S = 0.5
"""Window of the held-out window-RMS correlation (s): half a block, so that a 19-s recording's fold still has >= 10 windows."""

POOLED_LINE = "every second once, rendered by the fold's surface that did not see it"
"""What the pooled comparison is, for the output and the report."""

Ranges = list[tuple[int, int]]


def _merge(ranges: Ranges) -> Ranges:
    out: Ranges = []
    for a, b in ranges:
        if out and out[-1][1] == a:
            out[-1] = (out[-1][0], b)
        else:
            out.append((a, b))
    return out


def blocks(n: int, rate: float) -> Ranges:
    """One-second blocks covering ``n`` samples (the last one may be shorter)."""
    size = int(round(BLOCK_S * rate))
    return [(a, min(a + size, n)) for a in range(0, n, size)]


def _check_held(test: Ranges, n: int, rate: float, what: str, where: str) -> None:
    held = sum(b - a for a, b in test) / rate
    if held < MIN_HELD_S:
        raise DataError(f"{where}: {what} holds out {held:.2f} s, fewer than {MIN_HELD_S:g} s to compare "
                        f"(the recording is {n / rate:.1f} s); hold out more or record longer")
    fitted = (n - sum(b - a for a, b in test)) / rate
    if fitted < MIN_HELD_S:  # a fit on less than this fails deep in its filters (or fits nothing)
        raise DataError(f"{where}: {what} leaves {fitted:.2f} s to fit, fewer than {MIN_HELD_S:g} s "
                        f"(the recording is {n / rate:.1f} s); hold out less or record longer")


def holdout_split(n: int, rate: float, fraction: float, split: str, where: str = "recording") -> tuple[Ranges, Ranges]:
    """(training ranges, held-out ranges): the last ``fraction`` (``tail``) or interleaved one-second blocks (``blocks``).

    ``blocks`` holds out block k when floor((k + 1) x fraction) > floor(k x fraction): spread evenly, 0.5 every
    other second, 0.25 every fourth.
    """
    if not (np.isfinite(fraction) and 0.0 < fraction < 1.0):
        raise DataError(f"--holdout must be a fraction between 0 and 1 (e.g. 0.25), got {fraction!r}")
    if split == "tail":
        cut = int(round(n * (1.0 - fraction)))
        train, test = [(0, cut)], [(cut, n)]
    elif split == "blocks":
        bl = blocks(n, rate)
        held = [math.floor((k + 1) * fraction + 1e-9) > math.floor(k * fraction + 1e-9) for k in range(len(bl))]
        train = _merge([r for r, h in zip(bl, held, strict=True) if not h])
        test = _merge([r for r, h in zip(bl, held, strict=True) if h])
    else:
        raise DataError(f"--holdout-split must be tail or blocks, got {split!r}")
    _check_held(test, n, rate, f"--holdout {fraction:g} (--holdout-split {split})", where)
    return train, test


def fold_splits(n: int, rate: float, folds: int, where: str = "recording") -> list[tuple[Ranges, Ranges]]:
    """K-fold splits over interleaved one-second blocks: fold j holds out block k when k mod K == j."""
    if folds < 2:
        raise DataError(f"--folds must be at least 2, got {folds}")
    bl = blocks(n, rate)
    if len(bl) < 2 * folds:
        raise DataError(f"{where}: --folds {folds} needs at least {2 * folds} one-second blocks; the recording has {len(bl)}")
    out = []
    for j in range(folds):
        train = _merge([r for k, r in enumerate(bl) if k % folds != j])
        test = _merge([r for k, r in enumerate(bl) if k % folds == j])
        _check_held(test, n, rate, f"--folds {folds} (fold {j})", where)
        out.append((train, test))
    return out


@dataclass
class CrossValidation:
    """What :func:`evaluate_splits` found: one fit and one held-out comparison per split, and the pooled comparison."""

    fits: list[TextureFit]
    comparisons: list[Comparison]
    pooled: Comparison | None = None
    """K-fold only (None for one split): every held-out block compared at once, each rendered by the fold's surface
    that did not see it (module docstring, 'Pooled')."""
    in_sample: list[Comparison] = field(default_factory=list)
    """Per split: its surface compared on its own training ranges, the in-sample figure its held-out one is read
    against (fit on the even seconds, compare on the even and on the odd ones: the same render, other seconds)."""


def evaluate_splits(acc: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float,
                    splits: list[tuple[Ranges, Ranges]], opt: TextureOptions | None = None, material: str = "surface",
                    where: str = "recording", compare: CompareOptions | None = None) -> CrossValidation:
    """Fit on each split's training ranges and compare on its held-out ranges; with several splits, pool them too
    (module docstring)."""
    base = compare or CompareOptions()
    cmp_opt = replace(base, window_s=min(base.window_s, CV_WINDOW_S))
    x = highpassed(acc, rate, cmp_opt)
    pool = [np.zeros_like(x) for _ in range(cmp_opt.seeds)] if len(splits) > 1 else None
    out = CrossValidation([], [])
    for k, (train, test) in enumerate(splits):
        fit = fit_texture(acc, speed, force, rate, opt, material, f"{where} (fold {k} training blocks)", within=train)
        held = f"{where} (fold {k} held-out part)"
        renders, fold_opt = surface_renders(fit.model_set, acc, speed, force, rate, cmp_opt, held)
        ys = [highpassed(r, rate, fold_opt) for r in renders]
        out.fits.append(fit)
        out.comparisons.append(compare_highpassed(x, ys, rate, fold_opt, test, held))
        out.in_sample.append(compare_highpassed(x, ys, rate, fold_opt, train, f"{where} (fold {k} training blocks)"))
        if pool is not None:
            for y, p in zip(ys, pool, strict=True):
                for a, b in test:
                    p[a:b] = y[a:b]
    if pool is not None:
        tests = sorted(r for _train, test in splits for r in test)      # not merged: a range never spans two folds
        out.pooled = compare_highpassed(x, pool, rate, cmp_opt, tests, f"{where} (held-out blocks pooled)")
    return out


def _mean(values: list[Any]) -> Any:
    """Average of the folds' values: numbers (NaN/None left out; None when none is left; an integer all folds share
    stays that integer), lists of dicts item by item."""
    first = values[0]
    if isinstance(first, bool) or isinstance(first, str):
        return first
    if isinstance(first, int) and all(type(v) is int and v == first for v in values):
        return first                                      # a count the folds share (seeds): still a count
    if isinstance(first, (int, float)) or first is None:
        nums = [float(v) for v in values if v is not None and np.isfinite(v)]
        return float(np.mean(nums)) if nums else None
    if isinstance(first, dict):
        return {k: _mean([v.get(k) for v in values]) for k in first}
    if isinstance(first, list) and all(isinstance(v, list) and len(v) == len(first) for v in values):
        return [_mean([v[i] for v in values]) for i in range(len(first))]
    return [x for v in values for x in v]                 # windows: every fold's, one after the other


def holdout_doc(split: str, key: str, value: float | int, comparisons: list[Comparison],
                pooled: Comparison | None = None, in_sample: list[Comparison] | None = None) -> dict[str, Any]:
    """The --holdout-json document: {split, fraction or folds, block_s, results (one per fold, compare --json keys,
    and with ``in_sample`` the same keys for that fold's surface on its own training blocks), mean (the same keys
    averaged over the folds), pooled (the same keys for every held-out block at once, or null)}."""
    results = [c.to_json() for c in comparisons]
    if in_sample is not None:
        for r, c in zip(results, in_sample, strict=True):
            r["in_sample"] = c.to_json()
    mean = {k: _mean([r[k] for r in results]) for k in results[0]}
    return {"split": split, key: value, "block_s": BLOCK_S if split == "blocks" else None, "results": results, "mean": mean,
            "pooled": None if pooled is None else pooled.to_json()}


def describe_split(split: str, key: str, value: float | int, n: int, rate: float) -> str:
    """One line naming the split, for the output and the report."""
    if key == "folds":
        return (f"held out: {value}-fold cross-validation over interleaved {BLOCK_S:g}-s blocks (block k in fold k mod {value}); "
                f"{n / rate:.1f} s recording")
    if split == "tail":
        return f"held out: the last {value:g} of the recording ({value * n / rate:.1f} s), not used by the fit"
    return f"held out: {value:g} of the recording as interleaved {BLOCK_S:g}-s blocks, not used by the fit"
