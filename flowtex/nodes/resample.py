"""The ``resample`` node: integer-ratio rate change inside a graph (math in flowtex.dsp.resample_stream).

Rates: ``to_hz`` is the output rate; the input rate is that of the producer
(the graph's rate for a graph input, ``rate / every`` for a node). The node
runs at the faster of the two (it sets its own ``every`` through Node.own_every); a down-sampling
node writes a new output every D-th run and holds it in between, so nodes
with ``every: rate / to_hz`` downstream read each output sample once.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba import njit

from ..dsp.resample import DEFAULT_ATTEN_DB, MAX_FACTOR
from ..dsp.resample_stream import (
    ISTATE,
    PARAMS,
    STATE,
    history_length,
    latency_samples,
    polyphase_filter,
    resample_block,
    stream_params,
)
from ..errors import ParamError
from ..limits import MAX_EVERY
from ..node_api import Memory, Node, Param, Port


@njit(cache=True)
def _resample(p, s, si, x, y):
    resample_block(p, s, si, x, y)


def _every_of(rate: float, hz: float, param: str) -> int:
    k = rate / hz
    if k > MAX_EVERY:
        raise ParamError(param, f"{hz:g} Hz is more than {MAX_EVERY:,} ticks of the graph's base rate {rate:g} Hz; "
                                f"the lowest rate a node runs at is {rate / MAX_EVERY:g} Hz")
    if hz > rate or abs(k - round(k)) > 1e-9 * k:
        raise ParamError(param, f"{hz:g} Hz does not divide the graph's base rate {rate:g} Hz into whole ticks "
                                f"(use {rate:g} / k Hz, e.g. {rate / 2:g} or {rate / 4:g})")
    return int(round(k))


class Resample(Node):
    """Polyphase FIR resampling by an integer ratio (Kaiser design at build time); images/aliases atten_db down."""

    type_name = "resample"
    params = {
        "to_hz": Param("float", unit="Hz", min=0.0, min_exclusive=True,
                       doc="output rate; must be base rate / k; up or down by an integer factor from the input's rate"),
        "from_hz": Param("float", default=0.0, unit="Hz", min=0.0,
                         doc="input rate (0: the producer's rate); if given, it must be the producer's rate"),
        "atten_db": Param("float", default=DEFAULT_ATTEN_DB, unit="dB", min=40.0, max=150.0,
                          doc="attenuation of images (up) or aliases (down); passband ripple 20log10(1+10^(-atten/20)) dB"),
        "passband": Param("float", default=0.8, min=0.1, max=0.95,
                          doc="passband edge as a fraction of the lower Nyquist frequency (transition band up to 1.0)"),
    }
    inputs = {"x": Port(None, "*", "signal at the input rate")}
    outputs = {"y": Port("=x", "=x", "signal at to_hz, delayed by the stated latency")}
    latency_doc = ("(len(h) - 1) / 2 samples of the faster rate, shown by flowtex graph "
                   "(1 kHz -> 250 Hz at 80 dB: 108 samples = 108 ms)")
    kernel = _resample
    memory = Memory(params=PARAMS, state=STATE, istate=ISTATE)

    @classmethod
    def own_every(cls, params: dict[str, Any], rate: float, input_every: dict[str, int]) -> int | None:
        k_in = input_every.get("x", 1)
        if params["from_hz"] > 0.0 and _every_of(rate, params["from_hz"], "from_hz") != k_in:
            raise ParamError("from_hz", f"from_hz is {params['from_hz']:g} Hz but input 'x' arrives at {rate / k_in:g} Hz; "
                                        "drop from_hz or fix the producer's every:")
        return min(k_in, _every_of(rate, params["to_hz"], "to_hz"))

    def __init__(self, name, params, context):
        super().__init__(name, params, context)
        self.up, self.down = self._factors()

    def _factors(self) -> tuple[int, int]:
        rate = self.context.rate
        k_in = self.context.input_every.get("x", 1)
        k_out = _every_of(rate, self.p["to_hz"], "to_hz")
        if k_in == k_out:
            raise ParamError("to_hz", f"the input already arrives at {rate / k_in:g} Hz; remove the resample node")
        if max(k_in, k_out) // min(k_in, k_out) > MAX_FACTOR:  # the filter's length (and its design time) grows with it
            raise ParamError("to_hz", f"{rate / k_in:g} Hz -> {self.p['to_hz']:g} Hz is a factor of "
                                      f"{max(k_in, k_out) // min(k_in, k_out):,}; a resample node changes the rate by at "
                                      f"most {MAX_FACTOR}x up or down: chain two resample nodes")
        if k_in % k_out == 0:
            return k_in // k_out, 1
        if k_out % k_in == 0:
            return 1, k_out // k_in
        raise ParamError("to_hz", f"{rate / k_in:g} Hz -> {self.p['to_hz']:g} Hz is not an integer ratio; "
                                  "chain two resample nodes through a common rate, or resample the recording offline "
                                  "(flowtex resample)")

    def latency_samples(self) -> int:
        return latency_samples(self._filter())

    def _filter(self) -> np.ndarray:
        return polyphase_filter(self.up, self.down, self.p["atten_db"], self.p["passband"])

    def build(self, inputs, outputs):
        h = self._filter()
        params = stream_params(h, self.up, self.down)
        return self.pack_state({"ncoef": params.size - PARAMS.size(ncoef=0), "hist": history_length(h, self.up),
                                "w": inputs["x"].width}, params=params)
