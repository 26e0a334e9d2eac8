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
offset soaks up the whole force and leaves a mu 24-60x too small (issue 18).
``--offset yes`` fits T = mu N + b instead (a biased tangential sensor biases
a line through the origin by b sum N / sum N^2); such a fit cannot be stored
with ``--into``, which refuses it rather than drop b.

Every fit reports r2, the share of the tangential force's variance that the
normal force explains (the IRLS-weighted squared correlation of T and N, so
rejected stiction spikes do not count). Below ``LOW_R2`` the fit carries a
warning: mu is then the force ratio of a line through the origin, not a
measured dependence on the normal force.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.robust import irls_line
from ..errors import DataError
from .inputs import atomic_output, check_not_constant, load, signal

DEFAULT_MIN_FORCE_N = 0.1
"""Samples below this normal force are out of contact (the contact node's on threshold)."""


LOW_R2 = 0.25
"""Below this r2 (|correlation| < 0.5) the normal force explains little of the tangential force: the fit warns."""


@dataclass(frozen=True)
class FrictionFit:
    """mu (dimensionless) with its 95 % interval, the offset (N) if fitted, r2, a warning (or None), and what was used."""

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


def fit_friction(normal: np.ndarray, tangential: np.ndarray, min_force: float = DEFAULT_MIN_FORCE_N, offset: bool = False,
                 where: str = "recording") -> FrictionFit:
    """Robust mu from normal and tangential force (N): a line through the origin, or with an offset b when ``offset``.

    See the module docstring for the choice and for r2 and the warning.
    """
    normal = np.asarray(normal, float)
    tangential = np.asarray(tangential, float)
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
    line = irls_line(n, t, intercept=bool(offset), kind="bisquare")
    rejected = int(np.sum(line.weights == 0.0))
    r2 = explained_share(n, t, line.weights)
    warning = None
    if r2 < LOW_R2:
        ratio = float(line.weights @ t) / max(float(line.weights @ n), 1e-300)
        warning = (f"the normal force explains only {100 * r2:.1f} % of the tangential force's variance (r2 = {r2:.3f}, "
                   f"below {LOW_R2:g}): the friction force barely depends on the normal force here (force ratio "
                   f"{ratio:.3f}); " + ("mu is the slope of HaTT's line through the origin, i.e. about that ratio; "
                                        "the alternative, --offset yes (T = mu N + b), describes it as a constant force b "
                                        "but cannot be stored with --into" if not offset else
                                        "the offset b carries the force and mu is small; the alternative, "
                                        "HaTT's line through the origin (--offset no), gives mu near the force ratio "
                                        "and can be stored with --into"))
    return FrictionFit(line.slope, line.slope_ci, line.intercept, line.intercept_ci, int(normal.size), count, rejected,
                       line.scale, "IRLS bisquare, line " + ("with offset" if offset else "through the origin"), r2, warning)


def _forces(args: argparse.Namespace) -> tuple[np.ndarray, np.ndarray, Any]:
    rec, _rate = load(args.recording, args.rate)
    if args.force is not None:
        if args.normal is None:
            raise DataError(f"{args.recording}: --force needs --normal V (the surface normal signal, or x,y,z)")
        f3 = signal(rec, args.force, "--force", (3,))
        if args.normal in rec.arrays:
            nv = signal(rec, args.normal, "--normal", (3,))
        else:
            try:
                nv = np.broadcast_to(np.array([float(v) for v in args.normal.split(",")]), (f3.shape[0], 3))
            except ValueError:
                raise DataError(f"{args.recording}: no signal {args.normal!r} (--normal); give a signal name or a vector x,y,z") from None
        length = np.linalg.norm(nv, axis=1)
        if np.any(length < 1e-9):
            raise DataError(f"{args.recording}: signal {args.normal!r} (--normal) has zero-length normals; fix the normal")
        unit = nv / length[:, None]
        fn_signed = np.sum(f3 * unit, axis=1)
        normal = np.abs(fn_signed)
        tangential = np.linalg.norm(f3 - fn_signed[:, None] * unit, axis=1)
    else:
        if args.normal_force is None or args.friction_force is None:
            raise DataError(f"{args.recording}: give --normal-force N --friction-force T, or --force F3 --normal V")
        normal = signal(rec, args.normal_force, "--normal-force")
        ft = signal(rec, args.friction_force, "--friction-force", (1, 3))
        tangential = np.abs(ft) if ft.ndim == 1 else np.linalg.norm(ft, axis=1)
        check_not_constant(tangential, f"{args.recording}: signal {args.friction_force!r} (--friction-force)")
    check_not_constant(normal, f"{args.recording}: the normal force")
    return normal, tangential, rec


def store_mu(surface: str | Path, mu: float) -> None:
    """Write ``mu`` into a model set file (native JSON or HaTT XML, kept in its own format), atomically."""
    from ..io.hatt import write_hatt_xml
    from ..io.modelset import load_model_set, save_model_set

    ms = load_model_set(surface)
    ms.mu = float(mu)
    with atomic_output(surface) as tmp:
        if ms.metadata.get("format") == "hatt-xml":
            write_hatt_xml(ms, tmp, texture=int(ms.metadata.get("texture") or 0))
        else:
            save_model_set(ms, tmp)


def run(args: argparse.Namespace) -> int:
    normal, tangential, _rec = _forces(args)
    with_offset = args.offset == "yes"
    if with_offset and args.into:
        raise DataError(f"--into {args.into}: a model set stores mu only, so the offset of --offset yes would be dropped and "
                        "the rendered friction would be wrong; fit without --offset (HaTT's line through the origin) to store mu")
    fit = fit_friction(normal, tangential, args.min_force, with_offset, str(args.recording))
    if not with_offset and not (math.isfinite(fit.mu) and fit.mu >= 0):
        raise DataError(f"{args.recording}: the fitted mu is {fit.mu:g}; the tangential force does not grow with the normal "
                        "force (wrong signals or sign?)")
    doc = {"format": "flowtex-friction", "version": 1, "recording": str(args.recording), **asdict(fit)}
    print(f"friction: {fit.method}")
    print(f"{'mu':>8} {'95% CI':>19} {'offset N':>9} {'r2':>6} {'in contact':>10} {'rejected':>8} {'scale N':>8}")
    print(f"{fit.mu:8.4f} [{fit.mu_ci[0]:8.4f}, {fit.mu_ci[1]:8.4f}] {fit.offset:9.4f} {fit.r2:6.3f} {fit.in_contact:10d} "
          f"{fit.rejected:8d} {fit.residual_scale_n:8.4f}")
    if fit.warning:
        print(f"warning: {fit.warning}")
    with atomic_output(args.output) as tmp:
        tmp.write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    if args.into:
        store_mu(args.into, fit.mu)
        print(f"mu = {fit.mu:.4f} stored in {args.into}")
    print(f"-> {args.output}")
    return 0


def register_fit(kinds: Any) -> None:
    """Add ``flowtex fit friction``."""
    p = kinds.add_parser("friction", help="kinetic friction coefficient mu from normal and tangential forces",
                         description="Robust line through the origin of tangential vs normal force (samples in contact only), "
                                     "with the share of the tangential force the normal force explains (r2).")
    p.add_argument("recording", type=Path, help="recording (.npz, .csv, .h5)")
    p.add_argument("--normal-force", metavar="N", help="normal force signal (N)")
    p.add_argument("--friction-force", metavar="T", help="tangential (friction) force signal (N): 1-D magnitude or (n, 3)")
    p.add_argument("--force", metavar="F3", help="3-axis force signal (N), split into normal and tangential by --normal")
    p.add_argument("--normal", metavar="V", help="surface normal: a (n, 3) signal or a vector x,y,z")
    p.add_argument("--rate", type=float, help="sample rate (Hz) when the file states none")
    p.add_argument("--min-force", type=float, default=DEFAULT_MIN_FORCE_N, help="in contact from this normal force (N)")
    p.add_argument("--offset", choices=("yes", "no"), default="no",
                   help="no (default): HaTT's line through the origin, T = mu N; yes: T = mu N + b (cannot be stored with --into)")
    p.add_argument("-o", "--output", required=True, type=Path, help="output JSON (mu, mu_ci, ...)")
    p.add_argument("--into", metavar="SURFACE", help="also store mu in this model set (native JSON or HaTT XML)")
    p.set_defaults(func=run)
