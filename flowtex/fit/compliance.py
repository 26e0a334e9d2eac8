"""``flowtex fit compliance``: WHaT compliance k_c from stroking a surface (Guruswamy thesis sec. 5.2); the math is flowtex.dsp.compliance."""

from __future__ import annotations

import argparse
import inspect
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp import compliance as cm
from ..errors import DataError
from ..io.recordings import load_recording
from .inputs import check_plausible
from .recording_signals import recording_rate, signal, write_json_atomic

FORMAT_NAME = "flowtex-compliance"
FORMAT_VERSION = 1


def estimate_compliance(force: np.ndarray, accel: np.ndarray, rate_hz: float, contact: np.ndarray | None = None,
                        force_range: tuple[float, float] | None = None, **options: Any) -> dict[str, Any]:
    """k_c, sigma (m/s^2), valid and reason for one recording: force (n,) N, accel (n,) or (n, 1..3) m/s^2.

    ``contact`` (n,) 0/1 defaults to all ones (the force threshold still applies).
    ``force_range`` (N) sets the 24 bins; by default it is the range of the binned
    low-passed force, found by a first pass of the same kernel. ``options`` are
    :func:`flowtex.dsp.compliance.compliance_params` keywords (k_g, thresholds, ...).
    """
    force = np.ascontiguousarray(force, dtype=np.float64).ravel()
    accel = np.ascontiguousarray(np.asarray(accel, dtype=np.float64).reshape(force.size, -1))
    if accel.shape[1] > 3:
        raise ValueError(f"acceleration has {accel.shape[1]} axes; give 1 to 3")
    contact = np.ones(force.size) if contact is None else np.ascontiguousarray(contact, dtype=np.float64).ravel()
    check_plausible(force, "the normal force", "--force")  # a force x1e30 would otherwise fit "valid" with k_c x1e-30
    check_plausible(accel, "the acceleration", "--accel")
    threshold = options.get("force_threshold", inspect.signature(cm.compliance_params).parameters["force_threshold"].default)
    touching = (contact > 0.5) & (force > threshold)
    if touching.any() and not np.any(accel[touching] != accel[touching][:1]):  # in contact, yet no vibration at all
        raise ValueError(f"the acceleration (--accel) is {accel[touching][0, 0]:g} m/s^2 throughout the contact: "
                         "no vibration was recorded; check the accelerometer signal")
    out = np.zeros(5)
    if force_range is None:
        p = cm.compliance_params(rate_hz, -1e300, 1e300, **options)
        f_lp = np.zeros(force.size)
        binned = np.zeros(force.size, np.bool_)
        cm.compliance_trace(p, cm.new_state(), force, accel, contact, f_lp, binned)
        if not binned.any():
            return _result(out, rate_hz, force.size, (float("nan"), float("nan")), options, empty=True)
        force_range = (float(f_lp[binned].min()), float(np.nextafter(f_lp[binned].max(), np.inf)))
        if force_range[1] <= force_range[0]:
            force_range = (force_range[0], force_range[0] + 1e-9)
    p = cm.compliance_params(rate_hz, force_range[0], force_range[1], **options)
    cm.compliance_run(p, cm.new_state(), force, accel, contact, out)
    return _result(out, rate_hz, force.size, force_range, options)


def _result(out: np.ndarray, rate: float, n: int, force_range: tuple[float, float], options: dict, empty: bool = False) -> dict[str, Any]:
    reason = cm.REASON_TOO_FEW if empty else int(out[3])
    finite = not empty and np.isfinite(out[0])
    return {
        "format": FORMAT_NAME, "version": FORMAT_VERSION,
        "k_c": float(out[0]) if finite else None,
        "sigma": float(out[1]) if finite else None,
        "valid": bool(out[2] > 0.5) and not empty,
        "reason": cm.REASONS[reason],
        "bins_used": 0 if empty else int(out[4]),
        "force_range_n": [float(v) for v in force_range] if np.all(np.isfinite(force_range)) else None,
        "k_g": float(options.get("k_g", 1.0)),
        "rate_hz": rate, "samples": n,
    }


def register_fit(kinds: Any) -> None:
    """Add ``flowtex fit compliance``."""
    p = kinds.add_parser("compliance", help="WHaT compliance k_c from stroking (force vs RMS vibration, Guruswamy thesis sec. 5.2)",
                         description="Estimate the compliance coefficient k_c (0 soft .. 1 stiff) of the stroked surface in REC. "
                                     "An estimate that is not valid (smooth surface, poor fit) is still written, with a reason.")
    p.add_argument("recording", metavar="REC", help="recording (.npz/.csv/.h5)")
    p.add_argument("--force", required=True, metavar="F", help="signal name of the normal force (N)")
    p.add_argument("--accel", required=True, metavar="A", help="signal name of the acceleration (m/s^2, 1 or 3 axes)")
    p.add_argument("--contact", metavar="C", help="signal name of a 0/1 contact state (default: force above --force-threshold)")
    p.add_argument("-o", "--output", required=True, metavar="OUT.json", help="result file (JSON)")
    p.add_argument("--rate", type=float, help="sample rate in Hz if the recording does not state one")
    p.add_argument("--kg", type=float, default=1.0, help="k_g normalisation in N per m/s^2 (Guruswamy thesis eq. 6; default 1)")
    p.add_argument("--force-range", type=float, nargs=2, metavar=("LO", "HI"),
                   help="force range of the 24 bins in N (default: the range of the contact samples' low-passed force)")
    p.add_argument("--force-threshold", type=float, default=0.1, help="contact when the low-passed force exceeds this (N, default 0.1)")
    p.add_argument("--smooth-floor", type=float, default=0.1, help="RMS vibration floor of a smooth surface (m/s^2, default 0.1)")
    p.add_argument("--r2-min", type=float, default=0.8, help="least weighted R^2 of a valid line fit (default 0.8)")
    p.set_defaults(func=cmd_fit_compliance)


def cmd_fit_compliance(args: argparse.Namespace) -> int:
    rec = load_recording(args.recording)
    rate = recording_rate(rec, args.rate)
    force = signal(rec, args.force, "--force", (1,))
    accel = signal(rec, args.accel, "--accel", (1, 2, 3))
    contact = signal(rec, args.contact, "--contact", (1,)) if args.contact else None
    try:
        result = estimate_compliance(force, accel, rate, contact, tuple(args.force_range) if args.force_range else None,
                                     k_g=args.kg, force_threshold=args.force_threshold, smooth_floor=args.smooth_floor, r2_min=args.r2_min)
    except ValueError as exc:
        raise DataError(f"{args.recording}: {exc}") from None
    result["recording"] = str(Path(args.recording))
    write_json_atomic(args.output, result)
    kc = "n/a" if result["k_c"] is None else f"{result['k_c']:.4f}"
    print(f"{args.output}: k_c {kc}  sigma {result['sigma'] if result['sigma'] is None else round(result['sigma'], 4)}  "
          f"valid {str(result['valid']).lower()} ({result['reason']})")
    return 0
