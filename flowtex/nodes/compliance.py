"""compliance_estimator: streaming WHaT compliance k_c from normal force and vibration (Guruswamy thesis sec. 5.2)."""

from __future__ import annotations

import math

from numba import njit

from ..dsp.compliance import F_KC, F_SIGMA, F_VALID, FIT, FIT_LEN, PARAMS, STATE, compliance_fit, compliance_params, compliance_step
from ..dsp.contact import CONTACT_ON_N
from ..errors import ParamError
from ..node_api import Field, Layout, Memory, Node, Param, Port, PortSpec

COMPLIANCE = Memory(
    params=Layout("float", [*PARAMS.fields, Field("fallback_kc", 1, "k_c output while the estimate is not valid")]),
    state=Layout("float", [*STATE.fields, Field("fit", FIT_LEN, "the last fit: a FIT record "
                                                                "(flowtex.dsp.compliance.compliance_fit)")]))
"""The kernel's parameters and state (flowtex.dsp.compliance) with the node's fallback and last fit after them."""
P_FALLBACK = COMPLIANCE.params.const("fallback_kc")
S_FIT = COMPLIANCE.state.const("fit")


@njit(cache=True)
def _compliance(p, s, si, normal_force, acceleration, in_contact, k_c, sigma, valid):
    fit = s[S_FIT:S_FIT + FIT_LEN]
    for t in range(normal_force.shape[0]):
        if compliance_step(p, s, normal_force[t, 0], acceleration[t], in_contact[t, 0]):
            compliance_fit(p, s, fit)
        ok = fit[F_VALID] > 0.5
        k_c[t, 0] = fit[F_KC] if ok else p[P_FALLBACK]
        sigma[t, 0] = fit[F_SIGMA] if not math.isnan(fit[F_SIGMA]) else 0.0
        valid[t, 0] = 1.0 if ok else 0.0


class ComplianceEstimator(Node):
    """Compliance coefficient k_c (0 soft .. 1 stiff) updated while the user strokes: the same kernel as `flowtex fit compliance`.

    Each contact tick's low-passed force and RMS vibration are binned (24 equal
    bins over ``force_range``) and the weighted line fit is redone whenever a tick
    is binned (24 bins: a fixed cost); docs/compliance.md. Until the estimate is
    valid, ``k_c`` outputs ``fallback_kc``.
    """

    type_name = "compliance_estimator"
    params = {
        "force_range": Param("floats", default=(0.2, 5.0), unit="N", length=(2, 2), doc="force range split into 24 equal bins"),
        "k_g": Param("float", default=1.0, unit="kg", min=0.0, min_exclusive=True, doc="normalisation k_g (N per m/s^2): k_c = k_g * slope"),
        "force_cutoff_hz": Param("float", default=2.5, unit="Hz", min=0.0, min_exclusive=True, doc="force (and mean-square) low-pass"),
        "highpass_hz": Param("float", default=10.0, unit="Hz", min=0.0, min_exclusive=True, doc="acceleration high-pass (gravity, drift)"),
        "force_threshold": Param("float", default=CONTACT_ON_N, unit="N", min=0.0, doc="contact needs more force than this"),
        "vibration_threshold": Param("float", default=0.02, unit="m/s^2", min=0.0, doc="ticks with less RMS vibration are not binned"),
        "smooth_floor": Param("float", default=0.1, unit="m/s^2", min=0.0, doc="a surface whose bins all stay below is too smooth"),
        "r2_min": Param("float", default=0.8, min=0.0, max=1.0, doc="least weighted R^2 of a valid fit"),
        "min_per_bin": Param("int", default=10, min=2, doc="ticks a bin needs to count"),
        "settle_s": Param("float", default=0.2, unit="s", min=0.0, doc="skipped start of each contact session"),
        "fallback_kc": Param("float", default=0.5, doc="k_c output while the estimate is not valid"),
    }
    inputs = {
        "normal_force": Port((), "N", "normal force"),
        "acceleration": Port(None, "m/s^2", "acceleration, 1 or 3 axes"),
        "in_contact": Port((), "", "contact state 0/1 (unconnected: always 1; the force threshold still applies)", optional=True, default=1.0),
    }
    outputs = {
        "k_c": Port((), "", "compliance coefficient (fallback_kc until valid)"),
        "sigma": Port((), "m/s^2", "weighted residual standard deviation of the fit (0 before a fit)"),
        "valid": Port((), "", "1 when the estimate is valid"),
    }
    kernel = _compliance
    memory = COMPLIANCE

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        if inputs["acceleration"].width not in (1, 2, 3):
            raise ParamError("acceleration", f"acceleration must have 1 to 3 axes, got shape {inputs['acceleration'].shape}")
        return super().resolve(inputs)

    def build(self, inputs, outputs):
        p = self.p
        try:
            params = compliance_params(self.context.node_rate, p["force_range"][0], p["force_range"][1], k_g=p["k_g"],
                                       force_cutoff_hz=p["force_cutoff_hz"], highpass_hz=p["highpass_hz"],
                                       force_threshold=p["force_threshold"], vibration_threshold=p["vibration_threshold"],
                                       smooth_floor=p["smooth_floor"], r2_min=p["r2_min"], min_per_bin=p["min_per_bin"],
                                       settle_s=p["settle_s"])
        except ValueError as exc:
            name = "force_range" if "range" in str(exc) else ("force_cutoff_hz" if "force cutoff" in str(exc) else "highpass_hz")
            raise ParamError(name, str(exc)) from None
        names = [f.name for f in PARAMS.fields]
        return self.pack_state(params={**dict(zip(names, params, strict=True)), "fallback_kc": p["fallback_kc"]},
                               state={"fit": FIT.pack({"k_c": math.nan, "sigma": math.nan})})
