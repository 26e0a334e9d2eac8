"""Synthetic texture model sets built from known, stable ARMA models.

flowtex ships no HaTT file, so tests and the bundled example build their own
model sets here: every model is made from chosen poles and zeros (so its
stability and coefficients are known exactly), placed on a (speed, force) grid
or scatter, with HaTT's silent corner models at zero speed and zero force
(variance 0: no vibration when not moving or not touching).

The polynomial <-> LSF conversions here are *reference* implementations in
numpy (polynomial roots and products in float64). They build ground-truth data
and serve as independent oracles in tests; the per-tick conversion used while
rendering is ``flowtex.dsp.lsf.lsf_to_poly``.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial import Delaunay

from ..models.texture import TextureModelSet


def lsf_to_poly_reference(lsf: np.ndarray) -> np.ndarray:
    """A(z) = [1, a1, ..., ap] from ``p`` increasing LSFs, by float64 polynomial products.

    Even-index LSFs (0-based) are the root angles of the symmetric polynomial
    (times ``1 + z^-1`` for even p), odd-index ones those of the antisymmetric
    one (times ``1 - z^-1`` for even p, ``1 - z^-2`` for odd p); A is their
    mean with the last coefficient (zero) dropped.
    """
    lsf = np.asarray(lsf, dtype=np.float64)
    order = lsf.shape[0]
    sym = np.array([1.0])
    anti = np.array([1.0])
    for k, w in enumerate(lsf):
        quad = np.array([1.0, -2.0 * math.cos(w), 1.0])
        if k % 2 == 0:
            sym = np.convolve(sym, quad)
        else:
            anti = np.convolve(anti, quad)
    if order % 2 == 0:
        sym = np.convolve(sym, [1.0, 1.0])
        anti = np.convolve(anti, [1.0, -1.0])
    else:
        anti = np.convolve(anti, [1.0, 0.0, -1.0])
    a = 0.5 * (sym + anti)
    return a[:order + 1]


def poly_to_lsf_reference(a: np.ndarray) -> np.ndarray:
    """The ``p`` LSFs (radians, increasing in (0, pi)) of a minimum-phase A(z) = [1, a1, ..., ap].

    Roots of P(z) = A(z) - z^-(p+1) A(1/z) and Q(z) = A(z) + z^-(p+1) A(1/z)
    with numpy; the trivial roots at z = +-1 are dropped. Raises ValueError
    when A is not minimum phase (the angles would not interlace).
    """
    a = np.asarray(a, dtype=np.float64)
    order = a.shape[0] - 1
    ext = np.concatenate([a, [0.0]])
    ang = np.concatenate([np.angle(np.roots(ext - ext[::-1])), np.angle(np.roots(ext + ext[::-1]))])
    ang = np.sort(ang[(ang > 1e-9) & (ang < math.pi - 1e-9)])
    if ang.shape[0] != order or np.any(np.diff(ang) <= 0):
        raise ValueError("polynomial is not minimum phase (its LSFs do not interlace)")
    return ang


def poly_from_roots(radii: np.ndarray, angles: np.ndarray, real_roots: np.ndarray = ()) -> np.ndarray:
    """Real polynomial [1, c1, ...] with conjugate root pairs r e^{+-j theta} and the given real roots."""
    roots = [r * np.exp(1j * t) for r, t in zip(radii, angles, strict=True)]
    roots = roots + [np.conj(z) for z in roots] + [complex(x) for x in real_roots]
    return np.real(np.poly(np.array(roots))) if roots else np.array([1.0])


def _arma_at(speed: float, force: float, ar_order: int, ma_order: int, max_speed: float, max_force: float) -> tuple[np.ndarray, np.ndarray]:
    """A smooth, stable, minimum-phase ARMA pair whose resonances move with speed and force.

    Pole angles grow with speed (a faster stroke over the same texture gives
    higher temporal frequencies); pole radii grow with force (harder contact,
    sharper resonances) but stay below 0.98.
    """
    s = speed / max_speed
    f = force / max_force
    npair = ar_order // 2
    ang = np.linspace(0.25, 2.7, npair) * (0.8 + 0.25 * s) + 0.05 * f
    rad = 0.80 + 0.12 * f + 0.04 * np.cos(np.arange(npair) * 1.3 + s)
    a = poly_from_roots(rad, ang, [0.3 + 0.2 * s] if ar_order % 2 else [])
    mpair = ma_order // 2
    mang = np.linspace(0.4, 2.9, mpair) * (0.9 + 0.1 * s) + 0.1 * f
    mrad = 0.6 + 0.2 * f + 0.05 * np.sin(np.arange(mpair) + s)
    c = poly_from_roots(mrad, mang, [-0.2 - 0.1 * f] if ma_order % 2 else [])
    return a, c


def synthetic_model_set(speeds: np.ndarray, forces: np.ndarray, ar_order: int = 19, ma_order: int = 17,
                        grid: bool = True, sample_rate: float = 1000.0, mu: float = 0.3,
                        material: str = "synthetic", corners: bool = True) -> TextureModelSet:
    """A model set of known stable ARMA models at the given (speed mm/s, force N) points.

    ``grid=True`` places a model at every (speed, force) pair of the two
    lists (Romano 2012's table); ``grid=False`` takes ``speeds[i], forces[i]``
    as a scatter of points (HaTT's free-exploration segments). With
    ``corners`` a silent model (variance 0, coefficients copied from the
    nearest measured model) is added at speed 0 for every distinct force and
    at force 0 for every distinct speed, plus (0, 0): the lookup then fades to
    silence when the tool stops or lifts. The triangulation is scipy's
    Delaunay of the points; ``max_speed``/``max_force`` are the largest ones.
    """
    speeds = np.asarray(speeds, dtype=np.float64)
    forces = np.asarray(forces, dtype=np.float64)
    if grid:
        sg, fg = np.meshgrid(speeds, forces, indexing="ij")
        pts = np.column_stack([sg.ravel(), fg.ravel()])
    else:
        pts = np.column_stack([speeds, forces])
    max_speed = float(pts[:, 0].max())
    max_force = float(pts[:, 1].max())
    measured = len(pts)
    if corners:
        extra = [(0.0, f) for f in np.unique(pts[:, 1])] + [(s, 0.0) for s in np.unique(pts[:, 0])] + [(0.0, 0.0)]
        pts = np.vstack([pts, np.array(extra)])
    count = len(pts)
    ar_lsf = np.empty((count, ar_order))
    ma_lsf = np.empty((count, ma_order))
    ar_coeff = np.empty((count, ar_order + 1))
    ma_coeff = np.empty((count, ma_order + 1))
    variance = np.empty(count)
    gain = np.empty(count)
    scale = np.array([max_speed, max_force])
    for m in range(count):
        src = m
        if m >= measured:  # silent corner: copy the nearest measured model
            src = int(np.argmin(np.sum(((pts[:measured] - pts[m]) / scale) ** 2, axis=1)))
        s, f = pts[src]
        a, c = _arma_at(s, f, ar_order, ma_order, max_speed, max_force)
        ar_coeff[m] = a
        ma_coeff[m] = c
        ar_lsf[m] = poly_to_lsf_reference(a)
        ma_lsf[m] = poly_to_lsf_reference(c)
        gain[m] = 0.5 + 0.5 * s / max_speed + 0.2 * f / max_force
        variance[m] = 0.0 if m >= measured else 1e-3 * (0.2 + s / max_speed) * (0.3 + f / max_force)
    tri = Delaunay(pts).simplices.astype(np.int64)
    ms = TextureModelSet(material=material, sample_rate=sample_rate, speeds=pts[:, 0].copy(), forces=pts[:, 1].copy(),
                         triangles=tri, ar_lsf=ar_lsf, ma_lsf=ma_lsf, variance=variance, gain=gain,
                         max_speed=max_speed, max_force=max_force, mu=mu, ar_coeff=ar_coeff, ma_coeff=ma_coeff,
                         metadata={"generator": "flowtex.datasets.model_sets"})
    return ms.validate()


def cork_like_model_set(seed: int = 3) -> TextureModelSet:
    """45 models and 60 triangles at orders 19/17, the size of HaTT's cork surface.

    17 scattered (speed, force) points inside (20..380 mm/s) x (0.3..4 N),
    5 on the maximum-force edge, 5 on the maximum-speed edge, the
    (max speed, max force) corner, and 17 silent corner models (8 at speed 0,
    8 at force 0, and the origin) copying their nearest measured model with
    variance 0. A planar triangulation of n points with h on its hull has
    2n - 2 - h triangles: 90 - 2 - 28 = 60.
    """
    rng = np.random.default_rng(seed)
    max_speed, max_force = 380.0, 4.0
    measured = np.vstack([
        np.column_stack([rng.uniform(20.0, 370.0, 17), rng.uniform(0.3, 3.9, 17)]),
        np.column_stack([rng.uniform(40.0, 360.0, 5), np.full(5, max_force)]),
        np.column_stack([np.full(5, max_speed), rng.uniform(0.6, 3.6, 5)]),
        [[max_speed, max_force]],
    ])
    corner = np.array([(0.0, f) for f in np.linspace(0.5, max_force, 8)] + [(s, 0.0) for s in np.linspace(50.0, max_speed, 8)]
                      + [(0.0, 0.0)])
    allpts = np.vstack([measured, corner])
    full = synthetic_model_set(allpts[:, 0], allpts[:, 1], 19, 17, grid=False, corners=False, material="cork-like")
    n = len(measured)
    for k, c in enumerate(corner):
        src = int(np.argmin(np.sum(((measured - c) / [max_speed, max_force]) ** 2, axis=1)))
        m = n + k
        for key in ("ar_lsf", "ma_lsf", "ar_coeff", "ma_coeff", "gain"):
            getattr(full, key)[m] = getattr(full, key)[src]
        full.variance[m] = 0.0
    return full.validate()


def hard_model_set(ar_order: int = 12, ma_order: int = 10) -> TextureModelSet:
    """A small model set with the numerically hard features of real HaTT surfaces, for tests.

    * AR poles at radius 0.995..0.998 (one conjugate pair at 0.998 in every model);
    * MA LSFs with a gap of 2e-4 between two neighbours and the last LSF
      within 5e-4 of pi;
    * silent (variance 0) corner models at speed 0 and at force 0;
    * a hull that is not a rectangle: the (max speed, max force) corner has no
      model, so a saturated query lies outside the hull.

    Measured models sit on a 3 x 3 grid of speeds (60, 140, 220 mm/s) and
    forces (0.5, 1.5, 2.5 N). Stored coefficients are the float64 reference
    conversion of the stored LSFs, so file and LSFs agree to rounding.
    """
    if ar_order % 2 or ar_order < 4 or ma_order < 4:
        raise ValueError("hard_model_set needs an even AR order >= 4 and an MA order >= 4")
    speeds = [60.0, 140.0, 220.0]
    forces = [0.5, 1.5, 2.5]
    measured = [(s, f) for s in speeds for f in forces if not (s == speeds[-1] and f == forces[-1])]
    measured.append((180.0, 2.0))  # an interior model instead of the missing corner
    corner = [(0.0, f) for f in forces] + [(s, 0.0) for s in speeds] + [(0.0, 0.0)]
    pts = np.array(measured + corner)
    count = len(pts)
    npair = ar_order // 2
    ar_lsf = np.empty((count, ar_order))
    ma_lsf = np.empty((count, ma_order))
    variance = np.empty(count)
    gain = np.empty(count)
    for m, (s, f) in enumerate(pts):
        src = m
        if m >= len(measured):
            src = int(np.argmin(np.sum(((np.array(measured) - pts[m]) / [220.0, 2.5]) ** 2, axis=1)))
        s, f = pts[src]
        u = s / 220.0
        g = f / 2.5
        radii = np.full(npair, 0.995 + 0.002 * u)
        radii[npair // 2] = 0.998
        angles = np.linspace(0.3, 2.8, npair) + 0.05 * u + 0.02 * g
        ar_lsf[m] = poly_to_lsf_reference(poly_from_roots(radii, angles))
        lsf = np.linspace(0.4, 2.9, ma_order) + 0.03 * u - 0.02 * g
        lsf[2] = lsf[1] + 2e-4
        lsf[-1] = math.pi - 4e-4 - 5e-5 * g
        ma_lsf[m] = lsf
        variance[m] = 0.0 if m >= len(measured) else 2e-3 * (0.5 + u) * (0.5 + g)
        gain[m] = 0.8 + 0.3 * u
    ms = TextureModelSet(material="hard cases", sample_rate=1000.0, speeds=pts[:, 0].copy(), forces=pts[:, 1].copy(),
                         triangles=Delaunay(pts).simplices.astype(np.int64), ar_lsf=ar_lsf, ma_lsf=ma_lsf,
                         variance=variance, gain=gain, max_speed=220.0, max_force=2.5, mu=0.5,
                         ar_coeff=np.array([lsf_to_poly_reference(r) for r in ar_lsf]),
                         ma_coeff=np.array([lsf_to_poly_reference(r) for r in ma_lsf]),
                         metadata={"generator": "flowtex.datasets.model_sets.hard_model_set"})
    return ms.validate()


def hatt_like_model(seed: int, ar_order: int = 19, ma_order: int = 17, max_pole_radius: float = 0.985,
                    notch_radius: float = 0.9999) -> tuple[np.ndarray, np.ndarray]:
    """A random stable, minimum-phase ARMA pair (A, C) with the hard features of HaTT's models.

    Poles: conjugate pairs at random angles in (0.1, 3.0) rad with radii up to
    ``max_pole_radius`` (one pair exactly there), plus a real pole for odd p.
    Zeros: one pair at ``notch_radius`` within 0.02 rad of z = -1 (HaTT's
    MA zeros at |z| ~ 0.9999 near -1), the other pairs at radii 0.5..0.9,
    plus a real zero for odd q. Ground truth for fitting tests and benchmarks.
    """
    rng = np.random.default_rng(seed)
    npair = ar_order // 2
    ang = np.sort(rng.uniform(0.1, 3.0, npair))
    rad = rng.uniform(0.80, max_pole_radius, npair)
    if npair:
        rad[rng.integers(npair)] = max_pole_radius
    a = poly_from_roots(rad, ang, [rng.uniform(-0.5, 0.5)] if ar_order % 2 else [])
    mpair = ma_order // 2
    mang = np.r_[np.pi - rng.uniform(0.005, 0.02), rng.uniform(0.3, 2.8, max(mpair - 1, 0))][:mpair]
    mrad = np.r_[notch_radius, rng.uniform(0.5, 0.9, max(mpair - 1, 0))][:mpair]
    c = poly_from_roots(mrad, mang, [rng.uniform(-0.5, 0.5)] if ma_order % 2 else [])
    return a, c


def narrow_peak_model_set(count: int = 24, ar_order: int = 20, ma_order: int = 20, max_pole_radius: float = 0.9995,
                          seed: int = 0) -> TextureModelSet:
    """``count`` models (plus 3 silent corners) with the features that made resampling slow on real recordings.

    Copper-like: every model is :func:`hatt_like_model` at the given orders with
    poles up to ``max_pole_radius`` (one pair exactly there: a resonance
    2 (1 - r) fs / (2 pi) Hz wide, 0.16 Hz at 0.9995 and 1 kHz) and no notch at
    z = -1 (the zero pair sits at radius 0.5, so the spectrum stays high up to
    the Nyquist frequency, as in a fit of a recording without an anti-aliasing
    notch). Scattered (speed mm/s, force N) points in (20..300) x (0.2..3),
    Delaunay-triangulated, silent (variance 0) models at (0, 0), (0, 3) and
    (300, 0). Variances span 15 dB, as real surfaces' do.
    """
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(20.0, 300.0, count), rng.uniform(0.2, 3.0, count)])
    pairs = [hatt_like_model(seed * 1000 + m, ar_order, ma_order, max_pole_radius, notch_radius=0.5) for m in range(count)]
    variance = 1e-3 * 10.0 ** (rng.uniform(0.0, 1.5, count))
    return scattered_model_set("narrow peaks", pts, pairs, variance, "narrow_peak_model_set")


def scattered_model_set(material: str, points: np.ndarray, pairs: list[tuple[np.ndarray, np.ndarray]],
                        variance: np.ndarray, generator: str, max_speed: float = 300.0, max_force: float = 3.0) -> TextureModelSet:
    """A 1 kHz set of the models ``pairs`` [(A, C)] at ``points`` (speed mm/s, force N), plus 3 silent corners.

    The corners (variance 0) at (0, 0), (0, max_force) and (max_speed, 0) copy the last model's shape; the
    points are Delaunay-triangulated; every gain is 1 and mu 0.3.
    """
    pts = np.vstack([points, [[0.0, 0.0], [0.0, max_force], [max_speed, 0.0]]])
    pairs = list(pairs) + [pairs[-1]] * 3
    ar_order, ma_order = pairs[0][0].shape[0] - 1, pairs[0][1].shape[0] - 1
    ms = TextureModelSet(material=material, sample_rate=1000.0, speeds=pts[:, 0].copy(), forces=pts[:, 1].copy(),
                         triangles=Delaunay(pts).simplices.astype(np.int64),
                         ar_lsf=np.array([poly_to_lsf_reference(a) for a, _ in pairs]).reshape(len(pairs), ar_order),
                         ma_lsf=np.array([poly_to_lsf_reference(c) for _, c in pairs]).reshape(len(pairs), ma_order),
                         variance=np.r_[variance, np.zeros(3)], gain=np.ones(len(pairs)), max_speed=max_speed,
                         max_force=max_force, mu=0.3, ar_coeff=np.array([a for a, _ in pairs]),
                         ma_coeff=np.array([c for _, c in pairs]), metadata={"generator": f"flowtex.datasets.model_sets.{generator}"})
    return ms.validate()


def rough_model_set(count: int = 16, ar_order: int = 14, ma_order: int = 12, seed: int = 0) -> TextureModelSet:
    """``count`` models (plus 3 silent corners) whose spectra stay within a few dB of flat up to the Nyquist frequency.

    Like HaTT's rough surfaces (its bricks): every pole and zero at radius 0.2..0.45, angles spread over
    (0, pi), so nothing falls off before the Nyquist frequency. Upsampled, such a model must drop by tens of dB
    within the last few percent of the old band, which its own roots cannot do while following the band.
    """
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(20.0, 300.0, count), rng.uniform(0.2, 3.0, count)])
    pairs = []
    for _ in range(count):
        a = poly_from_roots(rng.uniform(0.2, 0.45, ar_order // 2), np.sort(rng.uniform(0.05, 3.1, ar_order // 2)),
                            [rng.uniform(-0.4, 0.4)] if ar_order % 2 else [])
        c = poly_from_roots(rng.uniform(0.2, 0.45, ma_order // 2), np.sort(rng.uniform(0.05, 3.1, ma_order // 2)),
                            [rng.uniform(-0.4, 0.4)] if ma_order % 2 else [])
        pairs.append((a, c))
    return scattered_model_set("rough", pts, pairs, 1e-2 * 10.0 ** rng.uniform(0.0, 1.5, count), "rough_model_set")


def edge_resonance_model_set(count: int = 16, ar_order: int = 10, ma_order: int = 8, seed: int = 0) -> TextureModelSet:
    """``count`` models (plus 3 silent corners), each with a sharp resonance between 0.85 and 0.99 x the Nyquist frequency.

    The hard case for resampling at both ends: upsampled, the peak sits at the old Nyquist's edge, inside or
    just above the band a resampled model must keep (0.9 x the old Nyquist); downsampled by 2, it lies above the
    new Nyquist and must not fold in. One pole pair at radius 0.97..0.995 there, the others as
    :func:`hatt_like_model`'s (radii 0.8..0.95), zeros at 0.5..0.9 with no notch at z = -1.
    """
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(20.0, 300.0, count), rng.uniform(0.2, 3.0, count)])
    pairs = []
    for k in range(count):
        npair = ar_order // 2
        ang = np.r_[math.pi * (0.85 + 0.14 * k / max(count - 1, 1)), np.sort(rng.uniform(0.2, 2.4, npair - 1))]
        rad = np.r_[rng.uniform(0.97, 0.995), rng.uniform(0.8, 0.95, npair - 1)]
        a = poly_from_roots(rad, ang, [rng.uniform(-0.5, 0.5)] if ar_order % 2 else [])
        c = poly_from_roots(rng.uniform(0.5, 0.9, ma_order // 2), np.sort(rng.uniform(0.3, 2.8, ma_order // 2)),
                            [rng.uniform(-0.5, 0.5)] if ma_order % 2 else [])
        pairs.append((a, c))
    return scattered_model_set("edge resonances", pts, pairs, 1e-3 * 10.0 ** rng.uniform(0.0, 1.5, count),
                               "edge_resonance_model_set")


def nyquist_pole_model_set(count: int = 12, seed: int = 0) -> TextureModelSet:
    """``count`` ARMA(6, 1) models (plus 3 silent corners) shaped like those ``fit texture`` fits on real-like recordings.

    Each has a real pole on the negative axis (z = -0.42..-0.52: a rise towards the Nyquist frequency), a real pole
    and a zero near z = 1 (the 10 Hz high-pass's notch at DC), a sharp resonance at 40-70 Hz (r 0.93..0.97) and a broad
    one at 180-200 Hz (r 0.72..0.78) -- the shape of the models a fit of
    :func:`flowtex.datasets.resonant.textured_exploration` gives (order 6,1). Upsampled from that start alone, the
    log-spectral fit ended 1-3 dB off for such models at every order and edge (docs/fitting.md).
    """
    rng = np.random.default_rng(seed)
    pts = np.column_stack([rng.uniform(130.0, 320.0, count), rng.uniform(0.3, 4.3, count)])
    pairs = []
    for _ in range(count):
        rad = np.r_[rng.uniform(0.93, 0.97), rng.uniform(0.72, 0.78)]
        ang = 2.0 * math.pi * np.r_[rng.uniform(40.0, 70.0), rng.uniform(180.0, 200.0)] / 1000.0
        a = poly_from_roots(rad, ang, [-rng.uniform(0.42, 0.52), rng.uniform(0.85, 0.92)])
        c = poly_from_roots(np.zeros(0), np.zeros(0), [rng.uniform(0.96, 0.985)])
        pairs.append((a, c))
    return scattered_model_set("Nyquist poles", pts, pairs, 1e-2 * 10.0 ** rng.uniform(0.0, 2.0, count),
                               "nyquist_pole_model_set", max_speed=320.0, max_force=4.3)
