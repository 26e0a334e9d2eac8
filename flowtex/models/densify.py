"""A texture model set with more models between its measured ones, rendering exactly as before at its own rate.

texture_lookup blends a triangle's three models linearly in barycentric
weights: the LSFs and the gain always, the loudness by the set's rule
(flowtex.models.rendering: the excitation variance, the output power, or the
log of the output power). :func:`densify_set` splits every edge between two
measured models (variance > 0) at its midpoint and puts there the model the
set itself renders at that point: the mean of the two LSF vectors and gains,
and the variance that gives the rule's loudness (the mean variance; the mean
output power; the geometric mean power). Every blended quantity is then linear
(or, for ``log_power``, log-linear) over each sub-triangle as it was over the
original triangle, so the denser set renders the same models everywhere
inside the measured models' triangles, up to rounding. A triangle with a
silent vertex (a corner model at speed 0 or force 0) has at most one such
edge and is split in two across it, so the triangulation stays conforming and
the silent corners stay as they were (silence at rest and HaTT's fade keep).

Why: a resampled set is fitted model by model, and resampling does not
commute with the blend between models (docs/fitting.md, 'Limit: between the
vertices'); with models at the midpoints the blends span half the distance,
and the resampled set follows its original along a path much more closely.
``hold`` and ``trend`` (flowtex.models.outside) take their nearest measured
model and their trend exponents over every measured model, the added ones
included, so beyond the measured models they can change slightly.

Units: speed mm/s, force N, variance (m/s^2)^2.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .rendering import resolve_rule
from .texture import TextureModelSet

MAX_LEVELS = 3
"""Most halvings :func:`densify_set` does: each multiplies the measured models by about 4."""


def measured_edges(ms: TextureModelSet) -> set[tuple[int, int]]:
    """Every edge of ``ms``'s triangulation between two measured models (variance > 0), as (low, high) indices."""
    measured = ms.variance > 0
    return {(min(a, b), max(a, b)) for t in ms.triangles for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))
            if measured[a] and measured[b]}


def densify_set(ms: TextureModelSet, levels: int = 1) -> TextureModelSet:
    """``ms`` with the midpoint of every edge between two measured models added, ``levels`` times (module docstring).

    The original models keep their indices (0..M-1) and values; ``metadata["densify"]`` records the levels and
    the models added. ``levels`` 0 returns ``ms`` itself. Raises ValueError for ``levels`` outside 0..MAX_LEVELS.
    """
    if not (isinstance(levels, int) and 0 <= levels <= MAX_LEVELS):
        raise ValueError(f"densify levels must be an integer from 0 to {MAX_LEVELS}, got {levels!r}")
    out = ms
    for _ in range(levels):
        out = split_edges(out, measured_edges(out))
    if levels:
        out = record_densify(out, ms, levels=levels)
    return out


def record_densify(dense: TextureModelSet, original: TextureModelSet, **info: object) -> TextureModelSet:
    """``dense`` with ``metadata["densify"]`` = ``info`` plus the models before and added (relative to ``original``)."""
    meta = dict(dense.metadata or {})
    meta["densify"] = {**info, "models_before": original.num_models, "models_added": dense.num_models - original.num_models}
    return dataclasses.replace(dense, metadata=meta)


def _closure(ms: TextureModelSet, edges: set[tuple[int, int]]) -> set[tuple[int, int]]:
    """``edges`` plus every splittable edge of each triangle that has two or more of them marked (red refinement).

    A triangle is then split in 4 (all three edges marked), in 2 (one) or not at all, never in 3 (two marked
    edges would leave a thin triangle); the closure repeats until no triangle has exactly two marked edges.
    """
    splittable = measured_edges(ms)
    marked = set(edges) & splittable
    tris = [tuple((min(a, b), max(a, b)) for a, b in ((t[0], t[1]), (t[1], t[2]), (t[2], t[0]))) for t in ms.triangles]
    changed = True
    while changed:
        changed = False
        for t in tris:
            if sum(e in marked for e in t) >= 2:
                for e in t:
                    if e in splittable and e not in marked:
                        marked.add(e)
                        changed = True
    return marked


def split_edges(ms: TextureModelSet, edges: set[tuple[int, int]]) -> TextureModelSet:
    """``ms`` with the model it renders at the midpoint of each of ``edges`` (between measured models) added.

    ``edges`` are (low, high) model indices; edges touching a silent model are ignored, and the closure
    (:func:`_closure`) may add a few so that the triangulation stays conforming. The models added are appended
    (every existing model keeps its index and values) and the set renders as before everywhere (module docstring).
    """
    from ..dsp.interp import model_output_powers

    marked = _closure(ms, edges)
    if not marked:
        return ms
    rule = resolve_rule(ms).interpolation
    power = model_output_powers(ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain)
    speeds, forces = list(ms.speeds), list(ms.forces)
    ar, ma, gain, var = list(ms.ar_lsf), list(ms.ma_lsf), list(ms.gain), list(ms.variance)
    mids: dict[tuple[int, int], int] = {}

    def midpoint(i: int, j: int) -> int | None:
        key = (min(i, j), max(i, j))
        if key not in marked:
            return None
        if key not in mids:
            mids[key] = len(speeds)
            speeds.append(0.5 * (ms.speeds[i] + ms.speeds[j]))
            forces.append(0.5 * (ms.forces[i] + ms.forces[j]))
            ar.append(0.5 * (ms.ar_lsf[i] + ms.ar_lsf[j]))
            ma.append(0.5 * (ms.ma_lsf[i] + ms.ma_lsf[j]))
            gain.append(0.5 * (ms.gain[i] + ms.gain[j]))
            if rule == "variance":
                var.append(0.5 * (ms.variance[i] + ms.variance[j]))
            else:
                target = 0.5 * (power[i] + power[j]) if rule == "power" else float(np.sqrt(power[i] * power[j]))
                unit = model_output_powers(ar[-1][None, :], ma[-1][None, :], np.ones(1), np.array([gain[-1]]))[0]
                var.append(target / unit)
        return mids[key]

    tris: list[tuple[int, int, int]] = []
    for i, j, k in (tuple(int(v) for v in t) for t in ms.triangles):
        a, b, c = midpoint(i, j), midpoint(j, k), midpoint(k, i)
        if a is not None and b is not None and c is not None:
            tris += [(i, a, c), (a, j, b), (c, b, k), (a, b, c)]
        elif a is not None:
            tris += [(i, a, k), (a, j, k)]
        elif b is not None:
            tris += [(j, b, i), (b, k, i)]
        elif c is not None:
            tris += [(k, c, j), (c, i, j)]
        else:
            tris.append((i, j, k))
    return dataclasses.replace(ms, speeds=np.array(speeds), forces=np.array(forces), triangles=np.array(tris, dtype=np.int64),
                               ar_lsf=np.array(ar), ma_lsf=np.array(ma), variance=np.array(var), gain=np.array(gain),
                               ar_coeff=None, ma_coeff=None).validate()
