"""Linear filter nodes: biquad, butterworth, first_order_lowpass, differentiator."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..dsp.filter_design import butterworth_sos
from ..dsp.filters import (
    SECTION_PARAMS,
    SECTION_STATE,
    difference_block,
    first_order_lowpass_block,
    lowpass_alpha,
    sos_block,
    sos_steady_state,
    sos_to_params,
)
from ..errors import ParamError
from ..node_api import Field, Layout, Memory, Node, Param, Port, PortSpec, check, simplify_unit

_STARTED = Layout("int", [Field("started", "steady", "init: steady only: 1 once the first input set the state")],
                  sizes=("steady",))
SOS = Memory(params=Layout("float", [Field("sos", f"{SECTION_PARAMS} * sections", "b0 b1 b2 a1 a2 per section "
                                                                                  "(flowtex.dsp.filters.SECTION)")],
                           sizes=("sections",)),
             state=Layout("float", [Field("z", f"w * sections * {SECTION_STATE}", "per channel and section: "
                                                                              "flowtex.dsp.filters.SECTION_MEMORY")],
                          sizes=("w", "sections")),
             istate=_STARTED)
"""A cascade of ``sections`` biquads filtering ``w`` channels (sos_block reads p and s whole: one field each)."""
LOWPASS = Memory(params=Layout("float", [Field("alpha", 1, "smoothing factor")]),
                 state=Layout("float", [Field("y", "w", "last output per channel")], sizes=("w",)), istate=_STARTED)
DIFFERENCE = Memory(params=Layout("float", [Field("rate", 1, "node rate, Hz")]),
                    state=Layout("float", [Field("x", "w", "last input per channel")], sizes=("w",)),
                    istate=Layout("int", [Field("started", 1, "1 once a sample was seen")]))
"""difference_block reads s (x) and si (started) whole: one field each."""
SI_STARTED = _STARTED.const("started")
P_ALPHA = LOWPASS.params.const("alpha")
S_Y = LOWPASS.state.const("y")
P_RATE = DIFFERENCE.params.const("rate")

INIT_PARAM = Param("choice", default="zero", choices=("zero", "steady"),
                   doc="initial state: zero (rest), or steady (as if the first input sample had always been applied, "
                       "like scipy's sosfilt_zi: no start-up transient)")


@njit(cache=True)
def _sos(p, s, si, x, y):
    if si.shape[0] > 0 and si[SI_STARTED] == 0 and x.shape[0] > 0:  # init: steady, first tick since reset
        sos_steady_state(p, s, x[0])
        si[SI_STARTED] = 1
    sos_block(p, s, x, y)


def _steady(init: str) -> int:
    """Length of the 'started' flag of a filter with an ``init`` parameter: one for steady, none for zero."""
    return 1 if init == "steady" else 0


class _SosNode(Node):
    inputs = {"x": Port(None, "*", "signal (each component filtered separately)")}
    outputs = {"y": Port("=x", "=x", "filtered signal")}
    kernel = _sos
    memory = SOS

    def sos(self) -> np.ndarray:
        raise NotImplementedError

    def build(self, inputs, outputs):
        coef = sos_to_params(self.sos())
        return self.pack_state({"sections": coef.size // SECTION_PARAMS, "w": inputs["x"].width,
                                "steady": _steady(self.p["init"])}, params={"sos": coef})


class Biquad(_SosNode):
    """One second-order section with given coefficients: (b0 + b1 z^-1 + b2 z^-2) / (a0 + a1 z^-1 + a2 z^-2)."""

    type_name = "biquad"
    params = {
        "b": Param("floats", doc="numerator b0, b1, b2", length=(3, 3)),
        "a": Param("floats", default=(1.0, 0.0, 0.0), doc="denominator a0, a1, a2 (a0 != 0)", length=(3, 3)),
        "init": INIT_PARAM,
    }

    def sos(self) -> np.ndarray:
        check(self.p["a"][0] != 0.0, "a", "a0 must be non-zero")
        poles = np.roots(self.p["a"])
        check(bool(np.all(np.abs(poles) < 1.0)), "a", f"the filter is unstable: pole radius {np.abs(poles).max():.6g} >= 1")
        return np.array([list(self.p["b"]) + list(self.p["a"])])


class Butterworth(_SosNode):
    """Butterworth filter designed with scipy.signal.butter as second-order sections."""

    type_name = "butterworth"
    params = {
        "kind": Param("choice", default="lowpass", choices=("lowpass", "highpass", "bandpass", "bandstop"), doc="response type"),
        "order": Param("int", doc="filter order (band filters have twice as many poles)", min=1, max=32),
        "cutoff_hz": Param("floats", unit="Hz", length=(1, 2), doc="cutoff in Hz, or [low, high] for band filters"),
        "init": INIT_PARAM,
    }

    def sos(self) -> np.ndarray:
        try:
            return butterworth_sos(self.p["kind"], self.p["order"], self.p["cutoff_hz"], self.context.node_rate)
        except ValueError as exc:
            raise ParamError("cutoff_hz", str(exc)) from None


@njit(cache=True)
def _lowpass(p, s, si, x, y):
    if si.shape[0] > 0 and si[SI_STARTED] == 0 and x.shape[0] > 0:  # init: steady (DC gain 1: the state is the input)
        for c in range(x.shape[1]):
            s[S_Y + c] = x[0, c]
        si[SI_STARTED] = 1
    first_order_lowpass_block(p[P_ALPHA], s, x, y)


class FirstOrderLowpass(Node):
    """First-order low-pass, y += alpha (x - y), pole at exp(-2 pi fc / fs)."""

    type_name = "first_order_lowpass"
    params = {
        "cutoff_hz": Param("float", unit="Hz", min=0.0, min_exclusive=True, doc="-3 dB corner of the analog prototype"),
        "initial": Param("float", default=0.0, doc="output before the first sample (with init: zero)"),
        "init": Param("choice", default="zero", choices=("zero", "steady"),
                      doc="zero: start from 'initial'; steady: start from the first input sample (no start-up transient)"),
    }
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "smoothed signal")}
    kernel = _lowpass
    memory = LOWPASS

    def build(self, inputs, outputs):
        rate = self.context.node_rate
        if self.p["cutoff_hz"] >= rate / 2:
            raise ParamError("cutoff_hz", f"cutoff {self.p['cutoff_hz']:g} Hz must be below Nyquist ({rate / 2:g} Hz)")
        alpha = lowpass_alpha(self.p["cutoff_hz"], rate)
        return self.pack_state({"w": inputs["x"].width, "steady": _steady(self.p["init"])}, params={"alpha": alpha},
                               state={"y": self.p["initial"]})


@njit(cache=True)
def _difference(p, s, si, x, y):
    difference_block(p[P_RATE], s, si, x, y)


def _per_second(unit: str) -> str:
    return simplify_unit(f"{unit}/s") if unit else "1/s"


class Differentiator(Node):
    """Backward difference times the rate: y[t] = (x[t] - x[t-1]) * fs; 0 on the first tick."""

    type_name = "differentiator"
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "", "rate of change per second", unit_doc="unit of x per second")}
    kernel = _difference
    memory = DIFFERENCE

    def resolve(self, inputs):
        return {"y": PortSpec(inputs["x"].shape, _per_second(inputs["x"].unit))}

    def build(self, inputs, outputs):
        return self.pack_state({"w": inputs["x"].width}, params={"rate": self.context.node_rate})
