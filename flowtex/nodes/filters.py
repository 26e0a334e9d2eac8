"""Linear filter nodes: biquad, butterworth, first_order_lowpass, differentiator."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..dsp.filter_design import butterworth_sos
from ..dsp.filters import (
    SECTION_STATE,
    difference_block,
    first_order_lowpass_block,
    lowpass_alpha,
    sos_block,
    sos_to_params,
)
from ..errors import ParamError
from ..node_api import Node, NodeState, Param, Port, PortSpec, check


@njit(cache=True)
def _sos(p, s, si, x, y):
    sos_block(p, s, x, y)


class _SosNode(Node):
    inputs = {"x": Port(None, "*", "signal (each component filtered separately)")}
    outputs = {"y": Port("=x", "=x", "filtered signal")}
    kernel = _sos

    def sos(self) -> np.ndarray:
        raise NotImplementedError

    def build(self, inputs, outputs):
        coef = sos_to_params(self.sos())
        sections = coef.size // 5
        return NodeState(params=coef, state=np.zeros(inputs["x"].width * sections * SECTION_STATE))


class Biquad(_SosNode):
    """One second-order section with given coefficients: (b0 + b1 z^-1 + b2 z^-2) / (a0 + a1 z^-1 + a2 z^-2)."""

    type_name = "biquad"
    params = {
        "b": Param("floats", doc="numerator b0, b1, b2", length=(3, 3)),
        "a": Param("floats", default=(1.0, 0.0, 0.0), doc="denominator a0, a1, a2 (a0 != 0)", length=(3, 3)),
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
    }

    def sos(self) -> np.ndarray:
        try:
            return butterworth_sos(self.p["kind"], self.p["order"], self.p["cutoff_hz"], self.context.node_rate)
        except ValueError as exc:
            raise ParamError("cutoff_hz", str(exc)) from None


@njit(cache=True)
def _lowpass(p, s, si, x, y):
    first_order_lowpass_block(p[0], s, x, y)


class FirstOrderLowpass(Node):
    """First-order low-pass, y += alpha (x - y), pole at exp(-2 pi fc / fs)."""

    type_name = "first_order_lowpass"
    params = {
        "cutoff_hz": Param("float", unit="Hz", min=0.0, min_exclusive=True, doc="-3 dB corner of the analog prototype"),
        "initial": Param("float", default=0.0, doc="output before the first sample"),
    }
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "smoothed signal")}
    kernel = _lowpass

    def build(self, inputs, outputs):
        rate = self.context.node_rate
        if self.p["cutoff_hz"] >= rate / 2:
            raise ParamError("cutoff_hz", f"cutoff {self.p['cutoff_hz']:g} Hz must be below Nyquist ({rate / 2:g} Hz)")
        alpha = lowpass_alpha(self.p["cutoff_hz"], rate)
        return NodeState(params=np.array([alpha]), state=np.full(inputs["x"].width, self.p["initial"]))


@njit(cache=True)
def _difference(p, s, si, x, y):
    difference_block(p[0], s, si, x, y)


def _per_second(unit: str) -> str:
    return f"{unit}/s" if unit else "1/s"


class Differentiator(Node):
    """Backward difference times the rate: y[t] = (x[t] - x[t-1]) * fs; 0 on the first tick."""

    type_name = "differentiator"
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "", "rate of change per second (unit of x per second)")}
    kernel = _difference

    def resolve(self, inputs):
        return {"y": PortSpec(inputs["x"].shape, _per_second(inputs["x"].unit))}

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.context.node_rate]), state=np.zeros(inputs["x"].width),
                         istate=np.zeros(1, np.int64))
