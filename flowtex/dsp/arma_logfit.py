"""Fit an ARMA model's log spectrum to a target, with its poles and zeros as the parameters.

The model's power spectrum in dB, 10 log10(K |C/A(e^jw)|^2), is a sum of one
term per root: for a conjugate pair r e^{+-j theta},
10 log10((1 - 2 r cos(w - theta) + r^2)(1 - 2 r cos(w + theta) + r^2)),
for a real root x, 10 log10(1 - 2 x cos w + x^2); zeros add, poles subtract,
and 10 log10 K is a free offset. The residuals are

* ``model_db - level_db`` at "fit" frequencies (their root mean square is the
  log-spectral distance, the quantity the caller must keep small), and
* ``max(0, model_db - level_db)`` at "ceiling" frequencies (one-sided: only
  where the model rises above a ceiling, e.g. a stopband),

each times its weight, minimised by a projected Levenberg-Marquardt
(:func:`fit_log_spectrum`) with the analytic Jacobian, both from one compiled
pass over the roots (:func:`log_spectrum_db`).

Why roots and not coefficients: every residual depends on a root through one
factor (the Jacobian has one cheap column pair per root and is well scaled),
stability and minimum phase are box bounds (radius <= ``max_radius``) instead of
a constraint that direct-form coefficients of clustered roots near z = 1 meet
only to many digits, and the criterion is the log-spectral distance itself,
not the prediction-error variance (which barely penalises a model lying
above a target's valleys). Radii are parameterised by u = ln(1 - r), which
spreads the sharp resonances near the unit circle over a usable range.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .poly import root_power_spectrum

DB = 10.0 / math.log(10.0)
"""dB per neper of power: 10 log10(x) = DB ln(x)."""

IMAG_TOL = 1e-9
"""Roots with |imag| below this are treated as real."""

STEPS = 100
"""Most accepted Levenberg-Marquardt steps of :func:`fit_log_spectrum`."""

EVALUATIONS = 120
"""Most residual evaluations (accepted and rejected steps, Jacobians) of :func:`fit_log_spectrum`: its cost bound."""

REL_TOL = 1e-4
""":func:`fit_log_spectrum` stops when an accepted step lowers the cost by less than this, relative."""

GOOD_DB = 0.02
""":func:`fit_log_spectrum` stops when the RMS fit residual is below this (dB): nothing left worth a step."""


RESTARTS = 6
"""Most further starts of :func:`fit_log_spectrum_restarted` (each a whole fit, bounded as the first)."""

RESTART_DB = 0.3
""":func:`fit_log_spectrum_restarted` starts again while the best fit's RMS residual over the two-sided frequencies is
above this (dB)."""

RESTART_JITTER = (0.5, 0.15, 0.2)
"""Standard deviations of a jittered start (:func:`restart_start`): ln(1 - r) of each pair, its angle (rad), each real root."""


def split_roots(poly: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(radii, angles in (0, pi]) of the upper-half conjugate pairs and the real roots of a real polynomial [1, c1..cn]."""
    if poly.shape[0] <= 1:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    roots = np.roots(poly)
    real = np.abs(roots.imag) <= IMAG_TOL * np.maximum(1.0, np.abs(roots))
    upper = roots[~real & (roots.imag > 0)]
    return np.abs(upper), np.angle(upper), np.sort(roots[real].real)


def real_poly(roots: np.ndarray) -> np.ndarray:
    """Monic real polynomial [1, c1, ...] in z^-1 with the given roots (conjugate pairs complete).

    Built from second-order sections multiplied lowest angle, highest angle,
    second lowest, ... (then the real roots): sections that all sit near z = 1
    would first build binomial-sized coefficients that later cancel.
    """
    roots = np.asarray(roots, dtype=np.complex128).ravel()
    real = np.abs(roots.imag) <= IMAG_TOL * np.maximum(1.0, np.abs(roots))
    upper = roots[~real & (roots.imag > 0)]
    upper = upper[np.argsort(np.angle(upper))]
    order = [i for pair in zip(range(upper.shape[0]), range(upper.shape[0] - 1, -1, -1), strict=True) for i in pair]
    seen: set[int] = set()
    out = np.array([1.0])
    for i in order:
        if i not in seen:
            seen.add(i)
            out = np.convolve(out, [1.0, -2.0 * upper[i].real, abs(upper[i]) ** 2])
    for x in np.sort(roots[real].real):
        out = np.convolve(out, [1.0, -x])
    return out


def _full_roots(radii: np.ndarray, angles: np.ndarray, real: np.ndarray) -> np.ndarray:
    z = radii * np.exp(1j * angles)
    return np.concatenate([z, np.conj(z), real.astype(np.complex128)])


class _Layout:
    """Where each root's parameters sit in the parameter vector: [dB offset, zero pairs (u, theta), zero reals, pole pairs, pole reals]."""

    def __init__(self, nzp: int, nzr: int, npp: int, npr: int):
        self.nzp, self.nzr, self.npp, self.npr = nzp, nzr, npp, npr
        self.zp = 1
        self.zr = self.zp + 2 * nzp
        self.pp = self.zr + nzr
        self.pr = self.pp + 2 * npp
        self.size = self.pr + npr

    def pack(self, offset_db, zrad, zang, zreal, prad, pang, preal) -> np.ndarray:
        x = np.empty(self.size)
        x[0] = offset_db
        x[self.zp:self.zr:2] = np.log1p(-zrad)
        x[self.zp + 1:self.zr:2] = zang
        x[self.zr:self.pp] = zreal
        x[self.pp:self.pr:2] = np.log1p(-prad)
        x[self.pp + 1:self.pr:2] = pang
        x[self.pr:] = preal
        return x

    def unpack(self, x: np.ndarray):
        zrad = -np.expm1(x[self.zp:self.zr:2])
        prad = -np.expm1(x[self.pp:self.pr:2])
        return (x[0], zrad, x[self.zp + 1:self.zr:2], x[self.zr:self.pp], prad, x[self.pp + 1:self.pr:2], x[self.pr:])


@njit(cache=True)
def _log_spectrum_kernel(cw: np.ndarray, sw: np.ndarray, x: np.ndarray, zp: int, zr: int, pp: int, pr: int,
                         jac: bool) -> tuple[np.ndarray, np.ndarray]:
    """Model dB at the frequencies whose cosines and sines are ``cw``, ``sw``, and (if ``jac``) its Jacobian
    (len(w) x len(x); else 0 x len(x)). ``zp``, ``zr``, ``pp``, ``pr``: where the zero pairs, zero reals, pole pairs and
    pole reals start in ``x`` (:class:`_Layout`). One pass per root over the frequencies, no temporaries: the fit
    evaluates this hundreds of times per model."""
    n = cw.shape[0]
    size = x.shape[0]
    s = np.full(n, x[0])
    J = np.zeros((n if jac else 0, size))
    if jac:
        J[:, 0] = 1.0
    for sign, p0, r0, end in ((1.0, zp, zr, pp), (-1.0, pp, pr, size)):
        for k in range(p0, r0, 2):  # conjugate pair r e^{+-j theta}, r = 1 - e^u
            r = -math.expm1(x[k])
            ct = math.cos(x[k + 1])
            st = math.sin(x[k + 1])
            for i in range(n):
                a = cw[i] * ct
                b = sw[i] * st
                cm = a + b  # cos(w - theta)
                cp = a - b  # cos(w + theta)
                dm = 1.0 - 2.0 * r * cm + r * r
                dp = 1.0 - 2.0 * r * cp + r * r
                s[i] += sign * (DB * math.log(dm * dp))
                if jac:
                    dr = DB * ((2.0 * r - 2.0 * cm) / dm + (2.0 * r - 2.0 * cp) / dp)
                    J[i, k] = sign * (dr * (r - 1.0))  # dr/du = -(1 - r)
                    c = sw[i] * ct
                    d = cw[i] * st
                    J[i, k + 1] = sign * (DB * 2.0 * r * ((c + d) / dp - (c - d) / dm))  # sin(w+th)/dp - sin(w-th)/dm
        for k in range(r0, end):  # real root
            xr = x[k]
            for i in range(n):
                d = 1.0 - 2.0 * xr * cw[i] + xr * xr
                s[i] += sign * (DB * math.log(d))
                if jac:
                    J[i, k] = sign * (DB * (2.0 * xr - 2.0 * cw[i]) / d)
    return s, J


def log_spectrum_db(w: np.ndarray, x: np.ndarray, lay: _Layout, jac: bool = False,
                    cs: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray | None]:
    """Model dB at w and (if ``jac``) its Jacobian in the parameters (len(w) x lay.size, else None).

    ``cs``: (cos w, sin w) when the caller has them (a fit evaluates the same frequencies many times)."""
    cw, sw = cs if cs is not None else (np.cos(w), np.sin(w))
    s, J = _log_spectrum_kernel(cw, sw, np.ascontiguousarray(x, dtype=np.float64), lay.zp, lay.zr, lay.pp, lay.pr, jac)
    return s, (J if jac else None)


def fit_log_spectrum(w: np.ndarray, level_db: np.ndarray, weight: np.ndarray, one_sided: np.ndarray,
                     a0: np.ndarray, c0: np.ndarray, pole_radius: float, zero_radius: float, iterations: int | None = None,
                     tol: float | None = None, evaluations: int | None = None, good_db: float | None = None,
                     offset_db: float | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """Least-squares fit of the model's dB spectrum (see the module docstring), started from (``a0``, ``c0``).

    ``w``: frequencies in rad/sample; ``level_db``: target (or ceiling, where
    ``one_sided``) in dB; ``weight``: residual weights. Pole radii stay in
    [0, ``pole_radius``], zero radii in [0, ``zero_radius``] (both < 1: stable,
    minimum phase; a pole much sharper than the grid resolves would be a
    spike between its frequencies, invisible to the fit), and pair
    angles in [0, pi]. The numbers of conjugate pairs and real roots are those
    of the start. Levenberg-Marquardt (Marquardt's diagonal scaling) with steps
    projected onto those bounds. Stopping rule (every bound is finite, so the fit
    always ends): it stops when an accepted step lowers the cost by less than
    ``tol`` relative, when the RMS weighted residual over the two-sided
    frequencies is below ``good_db`` dB (with no ceiling crossed by more than
    that), when no damping up to 1e10 finds a lower cost, after ``iterations``
    accepted steps, or after ``evaluations`` residual evaluations in all (each
    costs len(w) x roots; rejected trial steps count). None: :data:`STEPS`, :data:`REL_TOL`,
    :data:`EVALUATIONS`, :data:`GOOD_DB` (read at the call). Returns (poles, zeros, dB offset 10 log10 K, cost =
    sum of squared weighted residuals); ``offset_db`` fixes 10 log10 K instead (the level of the monic model
    then follows the target's: see flowtex.dsp.arma_resample.STOP_DEPTH_DB). Poles and zeros are complete root sets
    (conjugates included), :func:`real_poly` makes the polynomials.
    """
    iterations = STEPS if iterations is None else iterations
    tol = REL_TOL if tol is None else tol
    evaluations = EVALUATIONS if evaluations is None else evaluations
    good_db = GOOD_DB if good_db is None else good_db
    zrad, zang, zreal = split_roots(c0)
    prad, pang, preal = split_roots(a0)
    lay = _Layout(zrad.shape[0], zreal.shape[0], prad.shape[0], preal.shape[0])
    lo = np.full(lay.size, -np.inf)
    hi = np.full(lay.size, np.inf)
    for p0, r0, end, rmax in ((lay.zp, lay.zr, lay.pp, zero_radius), (lay.pp, lay.pr, lay.size, pole_radius)):
        lo[p0:r0:2], hi[p0:r0:2] = math.log1p(-rmax), 0.0
        lo[p0 + 1:r0:2], hi[p0 + 1:r0:2] = 0.0, math.pi
        lo[r0:end], hi[r0:end] = -rmax, rmax
    x = np.clip(lay.pack(0.0, np.minimum(zrad, zero_radius), zang, zreal, np.minimum(prad, pole_radius), pang, preal), lo, hi)
    two = ~one_sided
    w2 = weight * weight

    cs = (np.cos(w), np.sin(w))

    def residual(x, jac):
        """(weighted residuals, rows that count, Jacobian or None)."""
        s, J = log_spectrum_db(w, x, lay, jac=jac, cs=cs)
        d = s - level_db
        return weight * np.where(one_sided, np.maximum(d, 0.0), d), (two | (d > 0.0)), J

    s0, _ = log_spectrum_db(w, x, lay, cs=cs)
    if offset_db is None:
        x[0] = float(np.sum((w2 * (level_db - s0))[two]) / max(np.sum(w2[two]), 1e-300))  # best offset for the start
    else:
        x[0] = lo[0] = hi[0] = offset_db
    r, active, J = residual(x, True)
    cost = float(r @ r)
    lam = 1e-3
    floor = good_db ** 2 * float(np.sum(w2[two]))  # RMS weighted residual of good_db: nothing left worth a step
    used = 2
    for _ in range(iterations):
        if used >= evaluations:
            break
        Ja = (weight * active)[:, None] * J
        # einsum, not a BLAS product: small products on a loaded machine stall in multithreaded BLAS
        H = np.einsum("ij,ik->jk", Ja, Ja)
        g = np.einsum("ij,i->j", Ja, r)
        d = np.maximum(np.diag(H), 1e-12 * max(np.max(np.diag(H)), 1e-300))
        improved = False
        while lam < 1e10 and used < evaluations:
            try:
                step = -np.linalg.solve(H + lam * np.diag(d), g)
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            x_new = np.clip(x + step, lo, hi)
            r_new, _, _ = residual(x_new, False)
            used += 1
            cost_new = float(r_new @ r_new)
            if cost_new < cost:
                improved = True
                lam = max(lam / 3.0, 1e-9)
                break
            lam *= 10.0
        if not improved:
            break
        rel = (cost - cost_new) / max(cost, 1e-300)
        x = x_new
        r, active, J = residual(x, True)
        used += 1
        cost = float(r @ r)
        if rel < tol or cost < floor:
            break
    off, zr_, za_, zx_, pr_, pa_, px_ = lay.unpack(x)
    return _full_roots(pr_, pa_, px_), _full_roots(zr_, za_, zx_), float(off), cost


def two_sided_rms_db(poles: np.ndarray, zeros: np.ndarray, offset_db: float, w: np.ndarray, level_db: np.ndarray,
                     weight: np.ndarray, one_sided: np.ndarray) -> float:
    """Weighted RMS (dB) of ``model - level`` over the two-sided frequencies of a fit's result (the LSD it minimises)."""
    two = ~one_sided
    if not np.any(two):
        return 0.0
    model = offset_db + DB * np.log(root_power_spectrum(poles, zeros, w[two]))
    r = (model - level_db[two]) * weight[two]
    return math.sqrt(float(r @ r) / max(float(np.sum(weight[two] ** 2)), 1e-300))


def restart_start(a0: np.ndarray, c0: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Start ``k`` (1, 2, ...) of a restarted fit, from the first start's polynomials ``a0`` (poles) and ``c0`` (zeros).

    Levenberg-Marquardt ends in the local minimum nearest its start, and the start fixes how many roots are real
    (:func:`fit_log_spectrum` keeps them real). Start 1 joins the real roots two by two into conjugate pairs (radius
    the pair's geometric mean, angle pi / 2 for roots of opposite signs, else 0.05 rad), so that they can move to any
    frequency; starts 2 and on jitter every root by :data:`RESTART_JITTER`, seeded by ``k`` (the same starts on
    every run and machine)."""
    rng = np.random.default_rng(k)

    def moved(poly: np.ndarray) -> np.ndarray:
        rad, ang, real = split_roots(poly)
        if k == 1:
            real = np.sort(real)
            while real.shape[0] >= 2:
                x1, x2, real = real[-1], real[-2], real[:-2]
                rad = np.r_[rad, math.sqrt(abs(x1 * x2))]
                ang = np.r_[ang, 0.5 * math.pi if x1 * x2 < 0.0 else 0.05]
        else:
            du, dth, dx = RESTART_JITTER
            u = np.log1p(-np.minimum(rad, 0.999)) + du * rng.standard_normal(rad.shape[0])
            rad = -np.expm1(np.minimum(u, -1e-3))
            ang = np.clip(ang + dth * rng.standard_normal(ang.shape[0]), 0.01, math.pi - 0.01)
            real = np.clip(real + dx * rng.standard_normal(real.shape[0]), -0.95, 0.95)
        return real_poly(_full_roots(rad, ang, real))

    return moved(a0), moved(c0)


def fit_log_spectrum_restarted(w: np.ndarray, level_db: np.ndarray, weight: np.ndarray, one_sided: np.ndarray,
                               a0: np.ndarray, c0: np.ndarray, pole_radius: float, zero_radius: float,
                               restarts: int | None = None, restart_db: float | None = None,
                               offset_db: float | None = None) -> tuple[np.ndarray, np.ndarray, float, float]:
    """:func:`fit_log_spectrum` from (``a0``, ``c0``), then from :func:`restart_start`'s starts 1, 2, ... while the best
    fit so far leaves more than ``restart_db`` dB RMS over the two-sided frequencies, at most ``restarts`` more fits
    (None: :data:`RESTARTS`, :data:`RESTART_DB`). Returns the result of lowest cost, as :func:`fit_log_spectrum` does:
    its criterion decides, so a start never trades ceilings for the band."""
    restarts = RESTARTS if restarts is None else restarts
    restart_db = RESTART_DB if restart_db is None else restart_db
    best = fit_log_spectrum(w, level_db, weight, one_sided, a0, c0, pole_radius, zero_radius, offset_db=offset_db)
    for k in range(1, restarts + 1):
        if two_sided_rms_db(best[0], best[1], best[2], w, level_db, weight, one_sided) <= restart_db:
            break
        a1, c1 = restart_start(a0, c0, k)
        found = fit_log_spectrum(w, level_db, weight, one_sided, a1, c1, pole_radius, zero_radius, offset_db=offset_db)
        if found[3] < best[3]:
            best = found
    return best
