"""HaTT's renderer in plain float64 numpy: the reference texture_lookup's default must match on HaTT sets.

Written from what HaTT's renderer does per query (its AccSynthHashTable::
HashAndInterp2, Culbertson et al. 2014), independently of flowtex's
numba kernel (flowtex.dsp.interp) and of its LSF conversion (flowtex.dsp.lsf):

1. clamp: a speed above ``max_speed`` becomes ``max_speed - 0.01``, one below
   0.05 mm/s becomes 0.0001; the same for force (N);
2. find the file's triangle containing the point and its barycentric weights
   (HaTT's formula; a point on an edge may take either neighbour: the blend is
   continuous across edges);
3. blend AR LSFs, MA LSFs, excitation variance and MA gain linearly with them;
4. turn the LSFs into A(z), C(z) by float64 products of quadratics
   (flowtex.datasets.model_sets.lsf_to_poly_reference, numpy), where HaTT used
   float32 complex roots.

A clamped point outside the triangulation's hull is undefined in HaTT (its walk
prints "Unstable!"); the reference then takes the nearest point of the hull in
units of (max speed, max force), flowtex's documented rule, and says so.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from flowtex.datasets.model_sets import lsf_to_poly_reference
from flowtex.models.texture import TextureModelSet

LOW = 0.05
"""Speeds (mm/s) and forces (N) below this are at rest / out of contact for HaTT ..."""
LOW_VALUE = 0.0001
"""... and are replaced by this."""
MARGIN = 0.01
"""A query above the maximum becomes maximum - MARGIN."""


def read_hatt(path: Path) -> TextureModelSet:
    """Parse a HaTT ``Models_*.xml`` with ElementTree (not flowtex's reader) into the plain data object."""
    root = ET.parse(path).getroot()

    def values(el) -> np.ndarray:
        return np.array([float(v.text) for v in el.findall("value")])

    models = sorted(root.findall("model"), key=lambda m: int(m.findtext("modNum")))
    return TextureModelSet(
        material=root.findtext("material"), sample_rate=float(root.findtext("SampleRate")),
        speeds=values(root.find("speedList")), forces=values(root.find("forceList")),
        triangles=np.array([values(t) for t in root.findall("tri")], dtype=np.int64) - 1,
        ar_lsf=np.array([values(m.find("ARlsf")) for m in models]),
        ma_lsf=np.array([values(m.find("MAlsf")) for m in models]),
        variance=np.array([float(m.findtext("var")) for m in models]),
        gain=np.array([float(m.findtext("gain")) for m in models]),
        max_speed=float(root.findtext("maxSpeed")), max_force=float(root.findtext("maxForce")))


def clamp(x: float, top: float) -> float:
    """HaTT's clamping of one query coordinate."""
    if x > top:
        return top - MARGIN
    if x < LOW:
        return LOW_VALUE
    return x


def _weights(hs: TextureModelSet, t: np.ndarray, x: float, y: float) -> np.ndarray:
    s, f = hs.speeds[t], hs.forces[t]
    den = (f[1] - f[2]) * (s[0] - s[2]) + (s[2] - s[1]) * (f[0] - f[2])
    b1 = ((f[1] - f[2]) * (x - s[2]) + (s[2] - s[1]) * (y - f[2])) / den
    b2 = ((f[2] - f[0]) * (x - s[2]) + (s[0] - s[2]) * (y - f[2])) / den
    return np.array([b1, b2, 1.0 - b1 - b2])


def _hull_point(hs: TextureModelSet, x: float, y: float) -> tuple[float, float]:
    """Nearest point of the triangles' union, in units of (max speed, max force)."""
    scale = np.array([hs.max_speed, hs.max_force])
    q = np.array([x, y]) / scale
    best, best_d = None, np.inf
    for t in hs.triangles:
        pts = np.column_stack([hs.speeds[t], hs.forces[t]]) / scale
        for i in range(3):
            a, b = pts[i], pts[(i + 1) % 3]
            u = np.clip(np.dot(q - a, b - a) / np.dot(b - a, b - a), 0.0, 1.0)
            c = a + u * (b - a)
            d = np.sum((q - c) ** 2)
            if d < best_d:
                best, best_d = c, d
    return float(best[0] * scale[0]), float(best[1] * scale[1])


def locate(hs: TextureModelSet, x: float, y: float, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray, bool]:
    """(vertices, weights, inside) of a clamped query; ``inside`` False when it was projected onto the hull."""
    inside = True
    for _ in range(2):
        for t in hs.triangles:
            w = _weights(hs, t, x, y)
            if np.all(w >= -tol):
                return t, w, inside
        inside = False
        x, y = _hull_point(hs, x, y)
    t = min(hs.triangles, key=lambda t: -np.min(_weights(hs, t, x, y)))  # on the hull, up to rounding
    return t, _weights(hs, t, x, y), inside


def reference(hs: TextureModelSet, speed: float, force: float) -> tuple[np.ndarray, np.ndarray, float, float, bool]:
    """(A, C, gain, variance, inside) HaTT renders at one raw (speed mm/s, force N) query."""
    x, y = clamp(speed, hs.max_speed), clamp(force, hs.max_force)
    t, w, inside = locate(hs, x, y)
    ar, ma = lsf_to_poly_reference(w @ hs.ar_lsf[t]), lsf_to_poly_reference(w @ hs.ma_lsf[t])
    return ar, ma, float(w @ hs.gain[t]), float(w @ hs.variance[t]), inside


def rel_err(got: np.ndarray, want: np.ndarray) -> float:
    """max |got - want| / max |want| (coefficients: relative to the polynomial's size)."""
    want = np.asarray(want, float)
    scale = np.max(np.abs(want))
    return float(np.max(np.abs(np.asarray(got, float) - want)) / scale) if scale > 0 else float(np.max(np.abs(got)))
