"""``flowtex fit compliance``: WHaT compliance k_c from stroking a surface (Guruswamy thesis sec. 5.2); the math is flowtex.dsp.compliance."""

from __future__ import annotations

import inspect
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp import compliance as cm
from ..errors import DataError
from .inputs import check_plausible, load, signal

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
    out = np.zeros(cm.FIT_LEN)
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
    reason = cm.REASON_TOO_FEW if empty else int(out[cm.F_REASON])
    finite = not empty and np.isfinite(out[cm.F_KC])
    return {
        "format": FORMAT_NAME, "version": FORMAT_VERSION,
        "k_c": float(out[cm.F_KC]) if finite else None,
        "sigma": float(out[cm.F_SIGMA]) if finite else None,
        "valid": bool(out[cm.F_VALID] > 0.5) and not empty,
        "reason": cm.REASONS[reason],
        "bins_used": 0 if empty else int(out[cm.F_BINS]),
        "force_range_n": [float(v) for v in force_range] if np.all(np.isfinite(force_range)) else None,
        "k_g": float(options.get("k_g", 1.0)),
        "rate_hz": rate, "samples": n,
    }


def compliance_recording(recording: str | Path, force: str, accel: str, from_rate: float | None = None,
                         contact: str | None = None, force_range: tuple[float, float] | None = None,
                         **options: Any) -> dict[str, Any]:
    """:func:`estimate_compliance` of one recording (signals named as the options); the result names the recording."""
    rec, rate = load(recording, from_rate)
    f = signal(rec, force, "--force", (1,))
    a = signal(rec, accel, "--accel", (1, 2, 3))
    c = signal(rec, contact, "--contact", (1,)) if contact else None
    try:
        result = estimate_compliance(f, a, rate, c, force_range, **options)
    except ValueError as exc:
        raise DataError(f"{recording}: {exc}") from None
    result["recording"] = str(Path(recording))
    return result


def compliance_summary(result: dict[str, Any]) -> str:
    """One line: k_c, sigma, valid and the reason."""
    kc = "n/a" if result["k_c"] is None else f"{result['k_c']:.4f}"
    sigma = result["sigma"] if result["sigma"] is None else round(result["sigma"], 4)
    return f"k_c {kc}  sigma {sigma}  valid {str(result['valid']).lower()} ({result['reason']})"
