"""Resample a texture model set so that it renders like its original between the models too (``--densify auto``).

A resampled set is fitted model by model, and resampling does not commute with the blend texture_lookup makes
between neighbouring models (docs/fitting.md, 'Limit: between the vertices'). Adding the models the set itself
renders at edge midpoints (flowtex.models.densify) shortens the blends left to resampling. ``auto`` adds them
only where they are needed. It resamples the set and measures the path LSD
(flowtex.fit.quality.path_lsd_db: expected spectra of the rendered models along a path, original against
resampled) on the :data:`CHECK_PATHS`; while the worst exceeds :data:`PATH_MARGIN_DB`, it compares the two
sets' rendered models at every edge midpoint and triangle centroid, splits the edges where the LSD there
exceeds :data:`POINT_MARGIN_DB` (all three edges of a triangle whose centroid does), resamples the models
added (the fits already made are reused) and measures again, at most
:data:`flowtex.models.densify.MAX_LEVELS` times and up to :data:`MAX_GROWTH` times the set's models, keeping
the level whose worst path LSD is lowest (a level can be worse and the next better: a midpoint model can be
harder to resample than its ends). A set that
already agrees along the paths gains no model.

Why paths and not points: at single points between the models a resampled set is further off than along a
path, and splitting does not bring every point within 0.5 dB at any level (docs/fitting.md has the figures);
what a render shows, and what the target is about, is the spectrum along a path, where those errors average out.
A level whose resampled set has a model that misses its spectrum (flowtex.fit.resample.misses_text) is kept
only if every level has one: densifying never turns a set that can be written into one that is refused.

Units: rates Hz, LSD dB (flowtex.dsp.spectral.lsd_db, 15 Hz to 0.9 x the lower Nyquist).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..dsp.arma import arma_psd_rows
from ..dsp.spectral import lsd_db
from ..models.densify import MAX_LEVELS, densify_set, measured_edges, record_densify, split_edges
from ..models.texture import TextureModelSet
from .quality import common_band, lissajous_path, model_rows_at, path_lsd_db, psds_at
from .resample import FitCache, resample_model_set

PATH_MARGIN_DB = 0.4
"""``auto`` refines while a check path's LSD exceeds this (dB): 0.1 dB inside the 0.5 dB target, for paths
other than the check paths."""

POINT_MARGIN_DB = 0.5
"""... splitting the edges where the rendered models at a midpoint or centroid differ by more than this (dB)."""

CHECK_PATHS = (((7.3, 11.1), 1.0), ((3.1, 4.7), 0.3), ((13.3, 2.9), 2.0))
"""(cycles, phase) of the Lissajous figures (flowtex.fit.quality.lissajous_path, 5-95 % of the speed and force
range) along which ``auto`` measures: the first is the one docs/fitting.md quotes, the others cross the set at
other angles."""

MAX_GROWTH = 8
"""``auto`` refines no further than this many times the set's own models: it bounds the time (every added model
is fitted) on sets whose neighbouring models are unrelated, where each level gains little; HaTT's sets need
less (docs/fitting.md)."""

AUTO = "auto"
"""The ``densify`` value that refines adaptively."""

FREQ_POINTS = 600
"""Frequencies of the per-point LSD (flowtex.fit.quality.common_band)."""


def point_lsds(original: TextureModelSet, other: TextureModelSet, speeds: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """LSD (dB) between the models two sets render (texture_lookup's kernel and rule) at each (speed mm/s, force N).

    Each PSD at its set's own rate, 15 Hz to 0.45 x the lower rate: the band of flowtex.fit.quality.path_lsd_db.
    0 where the original renders silence (variance 0: a point between silent corner models), which a resampled
    set keeps.
    """
    f = common_band(original, other, FREQ_POINTS)
    a1, c1, g1, v1 = model_rows_at(original, speeds, forces)
    loud = g1 * g1 * v1 > 0
    out = np.zeros(g1.shape[0])
    speeds, forces = np.asarray(speeds, float).reshape(-1)[loud], np.asarray(forces, float).reshape(-1)[loud]
    want = arma_psd_rows(a1[loud], c1[loud], g1[loud], v1[loud], f, original.sample_rate)
    out[loud] = [lsd_db(a, b, f) for a, b in zip(psds_at(other, speeds, forces, f), want, strict=True)]
    return out


def _edges_to_split(ms: TextureModelSet, out: TextureModelSet, margin_db: float) -> set[tuple[int, int]]:
    """The edges whose midpoint, or whose triangle's centroid, renders more than ``margin_db`` off in ``out``."""
    edges = sorted(measured_edges(ms))
    tris = np.asarray(ms.triangles)
    e = np.array(edges, dtype=np.int64).reshape(-1, 2)
    speeds = np.r_[0.5 * ms.speeds[e].sum(axis=1), ms.speeds[tris].mean(axis=1)]
    forces = np.r_[0.5 * ms.forces[e].sum(axis=1), ms.forces[tris].mean(axis=1)]
    bad = point_lsds(ms, out, speeds, forces) > margin_db
    marked = {edges[i] for i in np.flatnonzero(bad[:len(edges)])}
    for t in tris[bad[len(edges):]]:
        a, b, c = (int(v) for v in t)
        marked |= {(min(a, b), max(a, b)), (min(b, c), max(b, c)), (min(c, a), max(c, a))}
    return marked


def resample_densified(ms: TextureModelSet, rate_hz: float, densify: int | str = AUTO,
                       progress: Callable[[int, int], None] | None = None, keep_order: bool = False,
                       extra_order: int | None = None, option: str = "--rate",
                       margin_db: float = PATH_MARGIN_DB,
                       point_margin_db: float = POINT_MARGIN_DB,
                       cache: FitCache | None = None) -> tuple[TextureModelSet, TextureModelSet]:
    """(the set as densified, it resampled to ``rate_hz`` Hz): ``models resample --densify``.

    ``densify`` N (0..MAX_LEVELS) adds every edge midpoint N times first (flowtex.models.densify.densify_set);
    ``"auto"`` refines where needed (module docstring). The other arguments are
    :func:`flowtex.fit.resample.resample_model_set`'s (``cache``: fits kept from earlier calls on sets sharing models,
reused and extended; every pass of ``auto`` shares one). With ``auto`` the densified set's ``metadata["densify"]``
    (carried into the resampled set) records the mode, the margins, the level kept and the levels tried, the
    models before and added, and the worst check-path LSD before (``path_lsd_db_before``) and after.
    """
    done_before = [0]  # fits of the earlier passes: one progress count over every pass

    def step(done: int, total: int) -> None:
        if progress is not None:
            progress(done_before[0] + done, done_before[0] + total)

    def resample(s: TextureModelSet, cache: FitCache | None = None) -> TextureModelSet:
        fits = [0]

        def count(done: int, total: int) -> None:
            fits[0] = done
            step(done, total)

        out = resample_model_set(s, rate_hz, count, keep_order=keep_order, extra_order=extra_order, option=option,
                                 cache=cache)
        done_before[0] += fits[0]
        return out

    if densify != AUTO:
        if not (isinstance(densify, int) and not isinstance(densify, bool) and 0 <= densify <= MAX_LEVELS):
            raise ValueError(f"densify must be {AUTO!r} or an integer from 0 to {MAX_LEVELS}, got {densify!r}")
        dense = densify_set(ms, densify)
        return dense, resample(dense, cache)
    cache = {} if cache is None else cache
    paths = [lissajous_path(ms, cycles=c, phase=ph) for c, ph in CHECK_PATHS]

    def worst_path(resampled: TextureModelSet) -> float:
        return max(path_lsd_db(ms, resampled, *p) for p in paths)

    dense, out = ms, resample(ms, cache)
    levels = [(worst_path(out), dense, out)]
    while levels[-1][0] > margin_db and len(levels) <= MAX_LEVELS:
        finer = split_edges(dense, _edges_to_split(dense, out, point_margin_db))
        if finer.num_models == dense.num_models:  # nothing left to split (only edges to silent models were marked)
            break
        if finer.num_models > MAX_GROWTH * ms.num_models:  # bounded time: unrelated neighbours gain little per level
            break
        dense = finer
        out = resample(dense, cache)
        levels.append((worst_path(out), dense, out))
    best = min(range(len(levels)), key=lambda k: (bool(levels[k][2].metadata["resample"]["misses"]), levels[k][0]))
    path, dense, out = levels[best]
    dense = record_densify(dense, ms, mode=AUTO, path_margin_db=margin_db, point_margin_db=point_margin_db,
                           levels=best, levels_tried=len(levels) - 1, path_lsd_db_before=levels[0][0], path_lsd_db=path)
    out.metadata["densify"] = dense.metadata["densify"]
    return dense, out


def densify_summary(source: str, original: TextureModelSet, dense: TextureModelSet) -> str | None:
    """One line on what densifying added to ``original`` (None when it added nothing), as the CLI prints it."""
    if dense.num_models == original.num_models:
        return None
    info = dense.metadata["densify"]
    how = (f"{info['levels']} level(s) of edge midpoints where needed, path LSD {info['path_lsd_db_before']:.2f} -> "
           f"{info['path_lsd_db']:.2f} dB" if info.get("mode") == AUTO else f"{info['levels']} level(s) of edge midpoints")
    return f"densified {source}: {original.num_models} -> {dense.num_models} models ({how})"
