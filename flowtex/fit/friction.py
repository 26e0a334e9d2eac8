"""``flowtex fit friction``: the kinetic friction coefficient mu_k from normal and tangential forces (Culbertson & Kuchenbecker 2017 sec. 3.3.1).

mu_k is the slope of a line through the origin of tangential vs normal force
(Culbertson & Kuchenbecker 2017), fitted robustly (IRLS, Tukey bisquare after a Huber start;
flowtex.dsp.robust) so that stiction spikes get weight 0, on the samples in
contact only (normal force >= ``--min-force``). Not the median of the
ratios T/N: with a force offset b the ratio is mu + b/N, which the many
samples at small N bias, while the line's slope weighs each sample by N.

The default is HaTT's Coulomb fit through the origin (``--offset no``): the
renderer's friction nodes take mu only, and on real recordings the
tangential force often barely varies with the normal force, where a free
offset soaks up the whole force and leaves a mu far too small (docs/fitting.md).
``--offset yes`` fits T = mu N + b instead (a biased tangential sensor biases
a line through the origin by b sum N / sum N^2); such a fit cannot be stored
with ``--into``, which refuses it rather than drop b.

The residual scale grows with the normal force by default (``--noise
force``): real tangential-force noise does, and one scale for every sample
rejects heavy contacts as outliers (docs/fitting.md). The scale is a power
law in N fitted robustly to the residuals, the line refitted on residuals
standardised by it (flowtex.dsp.hetero, Carroll & Ruppert's robust weighted
fit); ``--noise constant`` keeps one scale. The report says how many samples
were rejected, in how many stretches, and what share noise alone would put
past the rule (:func:`rejection_lines`).

Every fit reports r2, the share of the tangential force's variance that the
normal force explains (the IRLS-weighted squared correlation of T and N, so
rejected stiction spikes do not count). Below ``LOW_R2`` the fit carries a
warning: mu is then the force ratio of a line through the origin, not a
measured dependence on the normal force. The command line is
flowtex/cli/fit.py.
"""

from __future__ import annotations

import math
import os
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.contact import CONTACT_ON_N
from ..dsp.hetero import false_rejection_rate, irls_line_hetero, rejected_stretches
from ..dsp.robust import BISQUARE_C, RobustLine, irls_line
from ..errors import DataError
from .inputs import api_signals, atomic_output, check_not_constant, load, signal, signals_listed

DEFAULT_MIN_FORCE_N = CONTACT_ON_N
"""Samples below this normal force are out of contact (the contact node's on threshold)."""


NOISE_MODELS = ("force", "constant")
"""``--noise``: force (default: the residual scale is a power law in the normal force), constant (one scale)."""
TAIL_DOF = 5.0
"""The Student t whose false-rejection share the report quotes beside the Gaussian one (kurtosis 9: heavy tails)."""


LOW_R2 = 0.25
"""Below this r2 (|correlation| < 0.5) the normal force explains little of the tangential force: the fit warns."""


@dataclass(frozen=True)
class FrictionFit:
    """mu (dimensionless) with its 95 % interval, the offset (N) if fitted, r2, a warning (or None), and what was used.

    ``noise``: the noise model used (``force`` or ``constant``); ``scale_n``: the residual scale (N) at the normal
    forces ``scale_force_n`` (N: 5th, 50th, 95th percentile in contact; ``residual_scale_n`` is the middle one);
    ``noise_exponent``: d log scale / d log N there; ``rejected_*``: the samples with weight 0, their share of the
    samples in contact, their runs of consecutive samples and the longest; ``false_rejection_*``: the share
    Gaussian and Student t5 noise alone would put past the rule.
    """

    mu: float
    mu_ci: tuple[float, float]
    offset: float
    offset_ci: tuple[float, float]
    samples: int
    in_contact: int
    rejected: int
    residual_scale_n: float
    method: str
    r2: float
    warning: str | None
    noise: str
    scale_force_n: tuple[float, ...]
    scale_n: tuple[float, ...]
    noise_exponent: float
    rejected_share: float
    rejected_stretches: int
    longest_stretch_samples: int
    false_rejection_gaussian: float
    false_rejection_t5: float


def explained_share(x: np.ndarray, y: np.ndarray, weights: np.ndarray) -> float:
    """Weighted squared correlation of ``x`` and ``y`` (0..1): the share of y's variance a line in x explains.

    0 when either is constant over the samples with weight > 0.
    """
    w = np.asarray(weights, float)
    total = float(w.sum())
    if total <= 0.0:
        return 0.0
    dx = x - float(w @ x) / total
    dy = y - float(w @ y) / total
    sxx, syy, sxy = float(w @ (dx * dx)), float(w @ (dy * dy)), float(w @ (dx * dy))
    if sxx <= 0.0 or syy <= 0.0:
        return 0.0
    return min(1.0, sxy * sxy / (sxx * syy))


def _robust_line(n: np.ndarray, t: np.ndarray, offset: bool, noise: str,
                 forces: tuple[float, ...]) -> tuple[RobustLine, str, tuple[float, ...], float]:
    """(line, noise model used, residual scale (N) at ``forces`` (N), the scale's exponent at the middle force).

    ``force`` falls back to one scale when the line explains less than ``LOW_R2`` of the tangential force: the
    residuals are then the line's misfit, not noise, and a scale fitted to them would reweight the samples by how
    badly the line fits them (mu would no longer be the origin line's force ratio that the warning quotes).
    """
    line = irls_line(n, t, intercept=bool(offset), kind="bisquare")
    if noise == "force" and explained_share(n, t, line.weights) >= LOW_R2:
        hetero = irls_line_hetero(n, t, intercept=bool(offset), kind="bisquare")
        scales = tuple(float(v) for v in hetero.scale_at(np.array(forces)))
        return hetero.line, noise, scales, hetero.scale_function.exponent(forces[len(forces) // 2])
    return line, "constant", (line.scale,) * len(forces), 0.0


def fit_friction(normal: np.ndarray, tangential: np.ndarray, min_force: float = DEFAULT_MIN_FORCE_N, offset: bool = False,
                 where: str = "recording", noise: str = "force") -> FrictionFit:
    """Robust mu from normal and tangential force (N): a line through the origin, or with an offset b when ``offset``.

    ``noise="force"``: the residual scale is a power law in the normal force (flowtex.dsp.hetero), ``"constant"``:
    one scale for every sample. See the module docstring for the choices and for r2 and the warning.
    """
    if noise not in NOISE_MODELS:
        raise DataError(f"--noise {noise}: use one of {', '.join(NOISE_MODELS)}")
    _, (normal, tangential) = api_signals(where, None, normal=normal, tangential=tangential)
    keep = normal >= min_force
    count = int(keep.sum())
    if count == 0:
        raise DataError(f"{where}: no sample has a normal force >= {min_force:g} N (no contact anywhere); "
                        "check the signals' names and units (N), or lower --min-force")
    if count < 10:
        raise DataError(f"{where}: only {count} samples in contact (normal force >= {min_force:g} N); record longer")
    n, t = normal[keep], tangential[keep]
    if offset and float(np.ptp(n)) == 0.0:
        raise DataError(f"{where}: the normal force is constant while in contact; --offset yes needs a range of forces")
    quantiles = tuple(float(q) for q in np.quantile(n, (0.05, 0.5, 0.95)))
    line, noise, scales, exponent = _robust_line(n, t, offset, noise, quantiles)
    rejected = int(np.sum(line.weights == 0.0))
    stretches, longest = rejected_stretches(line.weights == 0.0)
    r2 = explained_share(n, t, line.weights)
    warning = None
    if r2 < LOW_R2:
        ratio = float(np.sum(t)) / max(float(np.sum(n)), 1e-300)   # mean T / mean N in contact: one figure for either fit
        warning = (f"the normal force explains only {100 * r2:.1f} % of the tangential force's variance (r2 = {r2:.3f}, "
                   f"below {LOW_R2:g}): the friction force barely depends on the normal force here (force ratio "
                   f"{ratio:.3f}); " + ("mu is the slope of HaTT's line through the origin, i.e. about that ratio; "
                                        "the alternative, --offset yes (T = mu N + b), describes it as a constant force b "
                                        "but cannot be stored with --into" if not offset else
                                        "the offset b carries the force and mu is small; the alternative, "
                                        "HaTT's line through the origin (--offset no), gives mu near the force ratio "
                                        "and can be stored with --into"))
    method = "IRLS bisquare, line " + ("with offset" if offset else "through the origin")   # the noise model: ``noise``
    return FrictionFit(line.slope, line.slope_ci, line.intercept, line.intercept_ci, int(normal.size), count, rejected,
                       scales[1], method, r2, warning, noise, quantiles, scales, exponent, rejected / count, stretches,
                       longest, false_rejection_rate(), false_rejection_rate(TAIL_DOF))


def friction_forces(rec: Any, normal_force: str | None = None, friction_force: str | None = None,
                    force3: str | None = None, normal: str | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(normal force (n,) N, tangential force magnitude (n,) N) from a recording.

    Either ``normal_force`` (1-D, N) and ``friction_force`` (1-D magnitude or (n, 3), N), or ``force3`` (n, 3) N split
    into normal and tangential parts by ``normal`` (a (n, 3) signal name or a vector ``"x,y,z"``).
    """
    where = rec.path
    if force3 is not None:
        if normal is None:
            raise DataError(f"{where}: --force3 needs --normal V (the surface normal signal, or x,y,z)")
        f3 = signal(rec, force3, "--force3", (3,))
        if normal in rec.arrays:
            nv = signal(rec, normal, "--normal", (3,))
        else:
            try:
                vector = np.array([float(v) for v in normal.split(",")])
                nv = np.broadcast_to(vector, (f3.shape[0], 3))
            except ValueError:
                raise DataError(f"{where}: no signal {normal!r} (--normal); give a signal name or a vector x,y,z") from None
            if not np.all(np.isfinite(vector)):
                raise DataError(f"--normal {normal}: the normal vector must be three finite numbers x,y,z")
        length = np.linalg.norm(nv, axis=1)
        if not np.all(np.isfinite(length)):
            raise DataError(f"{where}: signal {normal!r} (--normal) has non-finite normals; fix the normal")
        if np.any(length < 1e-9):
            raise DataError(f"{where}: signal {normal!r} (--normal) has zero-length normals; fix the normal")
        unit = nv / length[:, None]
        fn_signed = np.sum(f3 * unit, axis=1)
        n_force = np.abs(fn_signed)
        tangential = np.linalg.norm(f3 - fn_signed[:, None] * unit, axis=1)
    else:
        if normal_force is None or friction_force is None:
            raise DataError(f"{where}: give --force N (normal force) --friction-force T, or --force3 F3 --normal V; "
                            f"{signals_listed(rec)}")
        n_force = signal(rec, normal_force, "--force")
        ft = signal(rec, friction_force, "--friction-force", (1, 3))
        tangential = np.abs(ft) if ft.ndim == 1 else np.linalg.norm(ft, axis=1)
        check_not_constant(tangential, f"{where}: signal {friction_force!r} (--friction-force)")
    check_not_constant(n_force, f"{where}: the normal force")
    return n_force, tangential


def fit_friction_recording(recording: str | Path, from_rate: float | None = None, normal_force: str | None = None,
                           friction_force: str | None = None, force3: str | None = None, normal: str | None = None,
                           min_force: float = DEFAULT_MIN_FORCE_N, offset: bool = False,
                           noise: str = "force") -> tuple[FrictionFit, dict]:
    """Fit mu to one recording (see :func:`friction_forces` for the signals); returns the fit and its JSON document."""
    if not (math.isfinite(min_force) and min_force >= 0.0):
        raise DataError(f"--min-force {min_force:g}: valid range is 0 N or more")
    rec, _rate = load(recording, from_rate)
    n_force, tangential = friction_forces(rec, normal_force, friction_force, force3, normal)
    fit = fit_friction(n_force, tangential, min_force, offset, str(recording), noise)
    if not offset and not (math.isfinite(fit.mu) and fit.mu >= 0):
        raise DataError(f"{recording}: the fitted mu is {fit.mu:g}; the tangential force does not grow with the normal "
                        "force (wrong signals or sign?)")
    return fit, {"format": "flowtex-friction", "version": 1, "recording": str(recording), **asdict(fit)}


def friction_table(fit: FrictionFit) -> list[str]:
    """The lines ``flowtex fit friction`` prints (the warning last, when there is one)."""
    lines = [f"friction: {fit.method}",
             f"{'mu':>8} {'95% CI':>19} {'offset N':>9} {'r2':>6} {'in contact':>10} {'rejected':>8} {'scale N':>8}",
             f"{fit.mu:8.4f} [{fit.mu_ci[0]:8.4f}, {fit.mu_ci[1]:8.4f}] {fit.offset:9.4f} {fit.r2:6.3f} {fit.in_contact:10d} "
             f"{fit.rejected:8d} {fit.residual_scale_n:8.4f}"]
    lines += rejection_lines(fit)
    if fit.warning:
        lines.append(f"warning: {fit.warning}")
    return lines


def rejection_lines(fit: FrictionFit) -> list[str]:
    """What the table says about the noise model and the rejected samples (docs/fitting.md, "Rejected samples")."""
    f5, f50, f95 = fit.scale_force_n
    s5, s50, s95 = fit.scale_n
    if fit.noise == "force":
        model = (f"residual scale grows with the normal force as N^{fit.noise_exponent:.2f}: {s5:.4f} / {s50:.4f} / {s95:.4f} N "
                 f"at {f5:.2f} / {f50:.2f} / {f95:.2f} N (5th / 50th / 95th percentile of the normal force)")
    else:
        model = f"one residual scale, {s50:.4f} N, at every normal force"
    lines = [model]
    if fit.rejected:
        lines.append(f"rejected {fit.rejected} samples ({100 * fit.rejected_share:.2f} %) in {fit.rejected_stretches} "
                     f"stretch{'es' if fit.rejected_stretches != 1 else ''} (longest {fit.longest_stretch_samples} samples): "
                     f"residuals beyond {BISQUARE_C:g} residual scales, weight 0")
    else:
        lines.append(f"rejected no sample (none beyond {BISQUARE_C:g} residual scales)")
    lines.append(f"noise alone puts {100 * fit.false_rejection_gaussian:.4f} % of samples there if Gaussian, "
                 f"{100 * fit.false_rejection_t5:.2f} % if Student t ({TAIL_DOF:g} degrees of freedom); a share well above "
                 "that, in short stretches, is stiction or spikes, in stretches of a second or more, slow drift")
    return lines


def store_mu(surface: str | Path, mu: float) -> None:
    """Write ``mu`` into a model set file (native JSON or HaTT XML, kept in its own format), atomically.

    A symbolic link is followed: the file it points to is updated (renamed over, keeping its mode) and the link
    stays a link, so every other user of the model set sees the new mu.
    """
    from ..io.hatt import texture_index, write_hatt_xml
    from ..io.modelset import load_model_set, save_model_set

    surface = Path(os.path.realpath(surface))
    ms = load_model_set(surface)
    ms.mu = float(mu)
    xml = ms.metadata.get("format") == "hatt-xml"
    texture = texture_index(ms) if xml else 0
    with atomic_output(surface, keep_mode=True) as tmp:
        if xml:
            write_hatt_xml(ms, tmp, texture=texture)
        else:
            save_model_set(ms, tmp)
