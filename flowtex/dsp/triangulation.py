"""Point location and barycentric weights in a 2-D triangulation, allocation-free and loop-free.

Used by texture-model lookup: given a query (x, y) = (speed mm/s, force N),
find a triangle of the model set's triangulation that contains it and the
barycentric weights of its three vertices.

Everything lives in one packed float64 table built once by
:func:`pack_triangulation` (vertex coordinates, counter-clockwise triangles,
neighbours, boundary edges), so a graph node can keep it in its parameter
array. :func:`locate` then

1. tests the hint triangle (the previous answer: the fast path when the
   query moves a little between ticks);
2. walks from it towards the point (to the neighbour across the edge with the
   most negative weight), at most ``walk_limit`` steps;
3. if the walk leaves the triangulation or does not arrive (a walk can cycle
   in triangulations that are not Delaunay, as HaTT's reference renderer
   does), scans every triangle for the one the point is most inside;
4. if no triangle contains the point, the point is outside the hull: it is
   projected to the nearest point of the triangulation's boundary, measuring
   distance in coordinates scaled by ``(1/scale_x, 1/scale_y)`` (for model
   sets: by max speed and max force, so mm/s and N count alike), and the
   weights are those of the projected point on that boundary edge.

The weights returned are always >= 0 and sum to 1 (to rounding): a weight
computed as slightly negative (>= -``INSIDE_TOL``, points on edges) is set to
0 and the three are renormalised. A query exactly on a vertex gets the weight
exactly 1 on that vertex and exactly 0 on the others (the orientation
determinants are evaluated in a form that makes this exact). Queries should be
finite: the caller clamps them first (see :func:`clamp_query`, which maps
+-inf into range) and handles NaN itself (texture lookup holds its last model).
A NaN query still terminates, with meaningless but valid (>= 0, sum 1) weights.
"""

from __future__ import annotations

import numpy as np
from numba import njit

INSIDE_TOL = 1e-12
"""A barycentric weight >= -INSIDE_TOL counts as inside (points on edges, rounding)."""

# Header of the packed table.
H_NVERT = 0
H_NTRI = 1
H_NEDGE = 2
H_SCALE_X = 3
H_SCALE_Y = 4
H_WALK = 5
HEADER = 8


def table_offsets(nvert: int, ntri: int, nedge: int) -> tuple[int, int, int, int, int, int, int]:
    """Offsets in the packed table of vx, vy, tri (3/triangle), nbr (3/triangle), twice the area, boundary edges; and the size.

    Boundary edges take 2 values each: ``nedge`` owning triangles, then ``nedge`` slots (the edge
    opposite that vertex slot of the triangle).
    """
    vx = HEADER
    vy = vx + nvert
    tri = vy + nvert
    nbr = tri + 3 * ntri
    area = nbr + 3 * ntri
    edges = area + ntri
    return vx, vy, tri, nbr, area, edges, edges + 2 * nedge


def pack_triangulation(x: np.ndarray, y: np.ndarray, triangles: np.ndarray, scale_x: float = 1.0, scale_y: float = 1.0,
                       walk_limit: int | None = None) -> np.ndarray:
    """Build the packed float64 table :func:`locate` reads.

    ``x``, ``y``: (M,) vertex coordinates; ``triangles``: (T, 3) 0-based
    vertex indices (any orientation; degenerate triangles are refused with
    ValueError). ``scale_x``/``scale_y``: units of distance for the hull
    projection. ``walk_limit``: most walk steps before the full scan
    (default: T, which a walk in a Delaunay triangulation never needs).
    """
    x = np.ascontiguousarray(x, dtype=np.float64)
    y = np.ascontiguousarray(y, dtype=np.float64)
    tri = np.array(triangles, dtype=np.int64).reshape(-1, 3)
    nvert, ntri = x.shape[0], tri.shape[0]
    if ntri == 0:
        raise ValueError("a triangulation needs at least one triangle")
    if tri.min() < 0 or tri.max() >= nvert:
        raise ValueError("triangle vertex index out of range")
    if not (scale_x > 0 and scale_y > 0):
        raise ValueError("scale_x and scale_y must be > 0")
    twice_area = np.empty(ntri)
    for t in range(ntri):
        a, b, c = tri[t]
        d = _orient_py(x[a], y[a], x[b], y[b], x[c], y[c])
        if d < 0:
            tri[t, 1], tri[t, 2] = tri[t, 2], tri[t, 1]
            a, b, c = tri[t]
            d = _orient_py(x[a], y[a], x[b], y[b], x[c], y[c])
        if not d > 0:
            raise ValueError(f"triangle {t} ({a}, {b}, {c}) is degenerate")
        twice_area[t] = d
    # Neighbours: the triangle across the edge opposite slot k, i.e. edge (slot k+1, slot k+2).
    owners: dict[tuple[int, int], list[tuple[int, int]]] = {}
    for t in range(ntri):
        for k in range(3):
            a, b = int(tri[t, (k + 1) % 3]), int(tri[t, (k + 2) % 3])
            owners.setdefault((min(a, b), max(a, b)), []).append((t, k))
    nbr = np.full((ntri, 3), -1, dtype=np.int64)
    edges = []
    for own in owners.values():
        if len(own) == 1:
            edges.append(own[0])
        else:  # two owners in a proper triangulation; more only in overlapping files -- link the first two
            (t0, k0), (t1, k1) = own[0], own[1]
            nbr[t0, k0] = t1
            nbr[t1, k1] = t0
    edges.sort()
    nedge = len(edges)
    o_vx, o_vy, o_tri, o_nbr, o_area, o_etri, size = table_offsets(nvert, ntri, nedge)
    tab = np.zeros(size)
    tab[H_NVERT] = nvert
    tab[H_NTRI] = ntri
    tab[H_NEDGE] = nedge
    tab[H_SCALE_X] = scale_x
    tab[H_SCALE_Y] = scale_y
    tab[H_WALK] = ntri if walk_limit is None else int(walk_limit)
    tab[o_vx:o_vx + nvert] = x
    tab[o_vy:o_vy + nvert] = y
    tab[o_tri:o_tri + 3 * ntri] = tri.ravel()
    tab[o_nbr:o_nbr + 3 * ntri] = nbr.ravel()
    tab[o_area:o_area + ntri] = twice_area
    for e, (t, k) in enumerate(edges):
        tab[o_etri + e] = t
        tab[o_etri + nedge + e] = k
    return tab


def _orient_py(ax: float, ay: float, bx: float, by: float, cx: float, cy: float) -> float:
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True, inline="always")
def _orient(ax, ay, bx, by, cx, cy):
    # Same expression as _orient_py: with the query equal to a vertex, the
    # numerator of that vertex's weight is bit-identical to the denominator.
    return (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)


@njit(cache=True)
def triangle_weights(tab: np.ndarray, t: int, px: float, py: float, w: np.ndarray) -> float:
    """Raw barycentric weights of (px, py) in triangle ``t`` into ``w[0:3]``; returns the smallest."""
    nvert = int(tab[H_NVERT])
    ntri = int(tab[H_NTRI])
    o_vx = HEADER
    o_vy = o_vx + nvert
    o_tri = o_vy + nvert
    o_area = o_tri + 6 * ntri
    a = int(tab[o_tri + 3 * t])
    b = int(tab[o_tri + 3 * t + 1])
    c = int(tab[o_tri + 3 * t + 2])
    ax = tab[o_vx + a]
    ay = tab[o_vy + a]
    bx = tab[o_vx + b]
    by = tab[o_vy + b]
    cx = tab[o_vx + c]
    cy = tab[o_vy + c]
    d = tab[o_area + t]
    w0 = _orient(px, py, bx, by, cx, cy) / d
    w1 = _orient(ax, ay, px, py, cx, cy) / d
    w2 = _orient(ax, ay, bx, by, px, py) / d
    w[0] = w0
    w[1] = w1
    w[2] = w2
    return min(w0, min(w1, w2))


@njit(cache=True)
def _finish(tab: np.ndarray, t: int, w: np.ndarray, v: np.ndarray) -> int:
    """Clip weights to >= 0, renormalise, and write the triangle's vertex indices into ``v``."""
    nvert = int(tab[H_NVERT])
    o_tri = HEADER + 2 * nvert
    total = 0.0
    for k in range(3):
        if w[k] < 0.0:
            w[k] = 0.0
        total += w[k]
    if total != 1.0:
        for k in range(3):
            w[k] = w[k] / total
    for k in range(3):
        v[k] = int(tab[o_tri + 3 * t + k])
    return t


@njit(cache=True)
def locate(tab: np.ndarray, px: float, py: float, hint: int, w: np.ndarray, v: np.ndarray) -> int:
    """Find a triangle containing (px, py): returns its index, weights in ``w[0:3]``, vertex indices in ``v[0:3]``.

    ``hint`` is a triangle to try first (e.g. the previous answer; any value
    outside 0..T-1 means none). Never loops: at most ``walk_limit`` walk
    steps, then one scan of all triangles, then (outside the hull) one scan
    of the boundary edges. ``px``, ``py`` must be finite. See the module
    docstring for the guarantees on the weights.
    """
    nvert = int(tab[H_NVERT])
    ntri = int(tab[H_NTRI])
    o_nbr = HEADER + 2 * nvert + 3 * ntri
    t = hint if 0 <= hint < ntri else 0
    # 1-2. hint, then a bounded walk. A triangle the point is inside only within INSIDE_TOL (just across one of its
    # edges) is taken only if its neighbour across that edge does not hold the point with every weight >= 0: the
    # tolerance would otherwise lend a tiny weight to the far vertex (a point on a silent hull edge would render a
    # little of an interior model's variance)
    steps = int(tab[H_WALK])
    near = np.int64(-1)  # int64 from the start: numba would also compile the callees for a literal -1
    for _ in range(steps + 1):
        lo = triangle_weights(tab, t, px, py, w)
        if lo >= 0.0:
            return _finish(tab, t, w, v)
        if near >= 0:
            break
        if lo >= -INSIDE_TOL:
            near = t
        k = 0
        if w[1] < w[k]:
            k = 1
        if w[2] < w[k]:
            k = 2
        nxt = int(tab[o_nbr + 3 * t + k])
        if nxt < 0:
            break
        t = nxt
    if near >= 0:
        triangle_weights(tab, near, px, py, w)
        return _finish(tab, near, w, v)
    # 3. full scan: the triangle the point is most inside
    best = np.int64(-1)
    best_lo = -np.inf
    for u in range(ntri):
        lo = triangle_weights(tab, u, px, py, w)
        if lo > best_lo:
            best_lo = lo
            best = u
    if best_lo >= -INSIDE_TOL:
        triangle_weights(tab, best, px, py, w)
        return _finish(tab, best, w, v)
    # 4. outside the hull: nearest point of the boundary, in scaled coordinates
    return _project_to_hull(tab, px, py, w, v)


@njit(cache=True)
def _project_to_hull(tab: np.ndarray, px: float, py: float, w: np.ndarray, v: np.ndarray) -> int:
    nvert = int(tab[H_NVERT])
    ntri = int(tab[H_NTRI])
    nedge = int(tab[H_NEDGE])
    o_vx = HEADER
    o_vy = o_vx + nvert
    o_tri = o_vy + nvert
    o_etri = o_tri + 7 * ntri
    sx = 1.0 / tab[H_SCALE_X]
    sy = 1.0 / tab[H_SCALE_Y]
    qx = px * sx
    qy = py * sy
    best_d = np.inf
    best_e = 0
    best_s = 0.0
    for e in range(nedge):
        t = int(tab[o_etri + e])
        k = int(tab[o_etri + nedge + e])
        a = int(tab[o_tri + 3 * t + (k + 1) % 3])
        b = int(tab[o_tri + 3 * t + (k + 2) % 3])
        ax = tab[o_vx + a] * sx
        ay = tab[o_vy + a] * sy
        dx = tab[o_vx + b] * sx - ax
        dy = tab[o_vy + b] * sy - ay
        s = ((qx - ax) * dx + (qy - ay) * dy) / (dx * dx + dy * dy)
        if s < 0.0:
            s = 0.0
        elif s > 1.0:
            s = 1.0
        ex = ax + s * dx - qx
        ey = ay + s * dy - qy
        dist = ex * ex + ey * ey
        if dist < best_d:
            best_d = dist
            best_e = e
            best_s = s
    t = int(tab[o_etri + best_e])
    k = int(tab[o_etri + nedge + best_e])
    w[k] = 0.0
    w[(k + 1) % 3] = 1.0 - best_s
    w[(k + 2) % 3] = best_s
    return _finish(tab, t, w, v)


def locate_many(tab: np.ndarray, points: np.ndarray, hint: int = -1) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Python convenience: locate each row of ``points`` (N, 2), chaining hints; returns (triangles, weights, vertices)."""
    points = np.asarray(points, dtype=np.float64)
    return _locate_many(tab, points, hint)


@njit(cache=True)
def _locate_many(tab, points, hint):
    n = points.shape[0]
    tris = np.empty(n, dtype=np.int64)
    ws = np.empty((n, 3))
    vs = np.empty((n, 3), dtype=np.int64)
    w = np.empty(3)
    v = np.empty(3, dtype=np.int64)
    for i in range(n):
        hint = locate(tab, points[i, 0], points[i, 1], hint, w, v)
        tris[i] = hint
        ws[i, :] = w
        vs[i, :] = v
    return tris, ws, vs


@njit(cache=True)
def clamp_query(x: float, upper: float, margin: float, low: float, low_value: float) -> float:
    """HaTT's query saturation: x > upper -> upper - margin; x < low -> low_value; else x (inf included, NaN passes through)."""
    if x > upper:
        return upper - margin
    if x < low:
        return low_value
    return x
