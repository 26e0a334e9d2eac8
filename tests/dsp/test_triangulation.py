"""Point location in a triangulation: weights >= 0, sum 1, containing triangle, never loops.

References: scipy.spatial.Delaunay (find_simplex, its affine ``transform``
for barycentric coordinates, convex_hull) and plain numpy geometry.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial import Delaunay

from flowtex.datasets.model_sets import cork_like_model_set, hard_model_set
from flowtex.dsp.triangulation import clamp_query, locate_many, pack_triangulation


def scipy_bary(d: Delaunay, simplex: np.ndarray, pts: np.ndarray) -> np.ndarray:
    """Barycentric coordinates of pts in the given scipy simplices (vertex order of d.simplices)."""
    T = d.transform[simplex]
    b = np.einsum("nij,nj->ni", T[:, :2], pts - T[:, 2])
    return np.column_stack([b, 1.0 - b.sum(axis=1)])


def weights_by_vertex(d: Delaunay, tri: np.ndarray, w: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Reorder our (w, v) to scipy's vertex order of simplex ``tri``."""
    out = np.empty_like(w)
    for i in range(len(tri)):
        order = d.simplices[tri[i]]
        for k in range(3):
            out[i, list(order).index(v[i, k])] = w[i, k]
    return out


def hull_clamped(ms, pts):
    out = np.empty_like(pts)
    for i, (x, y) in enumerate(pts):
        out[i, 0] = clamp_query(x, ms.max_speed, 0.01, 0.05, 0.0001)
        out[i, 1] = clamp_query(y, ms.max_force, 0.01, 0.05, 0.0001)
    return out


def adversarial_points(ms, rng, n_random=3000):
    P = ms.points()
    tri = ms.triangles
    mids = np.concatenate([(P[tri[:, a]] + P[tri[:, b]]) / 2 for a, b in ((0, 1), (1, 2), (2, 0))])
    thirds = np.concatenate([P[tri[:, a]] + (P[tri[:, b]] - P[tri[:, a]]) / 3 for a, b in ((0, 1), (1, 2), (2, 0))])
    special = [0.0, -1.0, math.inf, -math.inf, 1e300, -1e300, 0.05, 0.0001, 0.049999, ms.max_speed, ms.max_force,
               ms.max_speed - 0.01, ms.max_force - 0.01, 1e-300, 5e-324]
    grid = np.array([(a, b) for a in special for b in special])
    rand = np.column_stack([rng.uniform(-0.1, 1.2, n_random) * ms.max_speed, rng.uniform(-0.1, 1.2, n_random) * ms.max_force])
    return np.vstack([P, mids, thirds, grid, rand])


@pytest.fixture(scope="module", params=["cork", "hard"])
def model_set(request):
    return cork_like_model_set() if request.param == "cork" else hard_model_set()


def test_weights_valid_and_point_contained(model_set):
    ms = model_set
    rng = np.random.default_rng(7)
    raw = adversarial_points(ms, rng)
    q = hull_clamped(ms, raw)
    assert np.all(np.isfinite(q))
    tab = pack_triangulation(ms.speeds, ms.forces, ms.triangles, ms.max_speed, ms.max_force)
    d = Delaunay(ms.points())
    assert np.array_equal(np.sort(d.simplices, axis=1), np.sort(ms.triangles, axis=1))  # same triangulation as ours
    tri, w, v = locate_many(tab, q)
    assert np.all(w >= 0.0)
    assert np.all(np.abs(w.sum(axis=1) - 1.0) <= 1e-12)
    # every vertex set is really the vertex set of the reported triangle
    assert np.array_equal(np.sort(v, axis=1), np.sort(ms.triangles[tri], axis=1))
    # the point represented by the weights
    rep = np.einsum("nk,nkj->nj", w, ms.points()[v])
    inside = d.find_simplex(q) >= 0
    scale = np.array([ms.max_speed, ms.max_force])
    # inside the hull: the weights reproduce the query, and scipy agrees the triangle contains it
    assert np.all(np.abs(rep[inside] - q[inside]) / scale <= 1e-12)
    sb = scipy_bary(d, tri[inside], q[inside])
    assert np.all(sb >= -1e-12)
    ours = weights_by_vertex(d, tri[inside], w[inside], v[inside])
    assert np.allclose(ours, sb, rtol=0, atol=1e-12)
    # strictly interior points: the very same triangle as scipy
    fs = d.find_simplex(q[inside])
    clear = sb.min(axis=1) > 1e-9
    assert np.array_equal(fs[clear], tri[inside][clear])


def test_outside_points_project_to_nearest_hull_point(model_set):
    ms = model_set
    rng = np.random.default_rng(3)
    scale = np.array([ms.max_speed, ms.max_force])
    q = np.column_stack([rng.uniform(-0.5, 1.5, 4000), rng.uniform(-0.5, 1.5, 4000)]) * scale
    d = Delaunay(ms.points())
    q = q[d.find_simplex(q) < 0]
    assert len(q) > 100
    tab = pack_triangulation(ms.speeds, ms.forces, ms.triangles, ms.max_speed, ms.max_force)
    tri, w, v = locate_many(tab, q)
    assert np.all(w >= 0) and np.all(np.abs(w.sum(axis=1) - 1) <= 1e-12)
    assert np.all(np.sum(w > 0, axis=1) <= 2)  # on an edge (or a vertex) of the boundary
    rep = np.einsum("nk,nkj->nj", w, ms.points()[v]) / scale
    # brute-force nearest point on the hull boundary, in scaled coordinates
    P = ms.points() / scale
    best = np.full(len(q), np.inf)
    for a, b in d.convex_hull:
        A, B = P[a], P[b]
        t = np.clip(((q / scale - A) @ (B - A)) / ((B - A) @ (B - A)), 0, 1)
        best = np.minimum(best, np.linalg.norm(A + t[:, None] * (B - A) - q / scale, axis=1))
    got = np.linalg.norm(rep - q / scale, axis=1)
    assert np.allclose(got, best, rtol=1e-9, atol=1e-12)


def test_exact_vertex_gives_one_hot_weights(model_set):
    ms = model_set
    tab = pack_triangulation(ms.speeds, ms.forces, ms.triangles, ms.max_speed, ms.max_force)
    for hint in (-1, 0, len(ms.triangles) - 1):
        tri, w, v = locate_many(tab, ms.points(), hint)
        for m in range(ms.num_models):
            k = list(v[m]).index(m)
            assert w[m, k] == 1.0
            assert np.all(np.delete(w[m], k) == 0.0)


def test_walk_limit_and_bad_hints_do_not_change_containment():
    ms = cork_like_model_set()
    rng = np.random.default_rng(11)
    q = np.column_stack([rng.uniform(0, ms.max_speed, 500), rng.uniform(0, ms.max_force, 500)])
    d = Delaunay(ms.points())
    q = q[d.find_simplex(q) >= 0]
    for limit in (0, 1, 3, None):
        tab = pack_triangulation(ms.speeds, ms.forces, ms.triangles, ms.max_speed, ms.max_force, walk_limit=limit)
        for hint in (-7, 0, 10**9):
            tri, w, v = locate_many(tab, q, hint)
            assert np.all(scipy_bary(d, tri, q) >= -1e-12)
            assert np.allclose(np.einsum("nk,nkj->nj", w, ms.points()[v]), q, rtol=0, atol=1e-10)


def test_non_delaunay_triangulation_is_handled():
    # Skinny fan triangles around an ellipse, overlapping the centre ones: not a Delaunay
    # triangulation (not even a proper one); the bounded walk plus scan must still find a
    # containing triangle and never loop.
    rng = np.random.default_rng(5)
    ang = np.sort(rng.uniform(0, 2 * np.pi, 12))
    x = np.concatenate([[0.0], 10 * np.cos(ang)])
    y = np.concatenate([[0.0], 3 * np.sin(ang)])
    # fan from vertex 1 (on the hull): long skinny triangles
    tris = np.array([[1, k, k + 1] for k in range(2, 12)] + [[0, 1, 2], [0, 12, 1]])
    area2 = (x[tris[:, 1]] - x[tris[:, 0]]) * (y[tris[:, 2]] - y[tris[:, 0]]) - (y[tris[:, 1]] - y[tris[:, 0]]) * (x[tris[:, 2]] - x[tris[:, 0]])
    tris = tris[np.abs(area2) > 1e-9]
    tab = pack_triangulation(x, y, tris, 10.0, 3.0, walk_limit=3)
    q = np.column_stack([rng.uniform(-12, 12, 2000), rng.uniform(-4, 4, 2000)])
    tri, w, v = locate_many(tab, q)
    assert np.all(w >= 0) and np.all(np.abs(w.sum(1) - 1) <= 1e-12)
    pts = np.column_stack([x, y])
    rep = np.einsum("nk,nkj->nj", w, pts[v])
    # points covered by some triangle are reproduced exactly
    covered = np.zeros(len(q), bool)
    for t in tris:
        a, b, c = pts[t]
        M = np.array([b - a, c - a]).T
        lam = np.linalg.solve(M, (q - a).T).T
        covered |= (lam.min(1) >= 1e-9) & (lam.sum(1) <= 1 - 1e-9)
    assert covered.sum() > 100
    assert np.allclose(rep[covered], q[covered], atol=1e-9)


def test_degenerate_triangle_refused():
    with pytest.raises(ValueError, match="degenerate"):
        pack_triangulation(np.array([0.0, 1.0, 2.0]), np.array([0.0, 1.0, 2.0]), np.array([[0, 1, 2]]))


@pytest.mark.parametrize("x, want", [
    (math.inf, 9.99), (1e300, 9.99), (10.0, 10.0), (10.000001, 9.99), (5.0, 5.0), (0.05, 0.05),
    (0.049, 0.0001), (0.0, 0.0001), (-1.0, 0.0001), (-math.inf, 0.0001),
])
def test_clamp_query_follows_hatt(x, want):
    assert clamp_query(x, 10.0, 0.01, 0.05, 0.0001) == want


def test_clamp_query_passes_nan_through():
    assert math.isnan(clamp_query(math.nan, 10.0, 0.01, 0.05, 0.0001))


def test_nan_query_terminates_with_valid_weights():
    # Callers must not pass NaN (texture lookup holds its model instead), but even then: no loop, weights sum to 1.
    ms = hard_model_set()
    tab = pack_triangulation(ms.speeds, ms.forces, ms.triangles, ms.max_speed, ms.max_force)
    tri, w, v = locate_many(tab, np.array([[math.nan, 1.0], [1.0, math.nan], [math.nan, math.nan]]))
    assert np.all(w >= 0) and np.all(w.sum(axis=1) == 1.0)
    assert np.all((0 <= tri) & (tri < len(ms.triangles)))
