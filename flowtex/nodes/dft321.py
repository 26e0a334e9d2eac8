"""The streaming ``dft321`` node: 3-axis signal -> 1 axis with the same spectral power (math in flowtex.dsp.dft321_stream)."""

from __future__ import annotations

from numba import njit

from ..dsp.dft321_stream import (
    ISTATE,
    PARAMS,
    STATE,
    WINDOWS,
    check_config,
    dft321_stream_block,
    latency_samples,
    param_sizes,
    stream_params,
)
from ..errors import ParamError
from ..node_api import Memory, Node, Param, Port, PortSpec


@njit(cache=True)
def _dft321(p, s, si, x, y):
    dft321_stream_block(p, s, si, x, y)


class Dft321(Node):
    """DFT321 on overlapping frames: |Y| = sqrt(|X|^2+|Y|^2+|Z|^2) per bin, phase of X+Y+Z; one moving axis comes back exactly."""

    type_name = "dft321"
    params = {
        "frame": Param("int", default=128, min=4, max=1024, doc="frame length in samples (latency frame - 1); a power of two for the fft method"),
        "hop": Param("int", default=64, min=1, doc="samples between frames; must divide frame and be <= frame/2"),
        "window": Param("choice", default="hann", choices=WINDOWS,
                        doc="analysis window (sqrt_hann: also synthesis); COLA at every allowed hop"),
        "method": Param("choice", default="auto", choices=("auto", "fft", "dft"),
                        doc="transform: in-place radix-2 fft (power-of-two frames), direct dft (any frame); auto picks fft "
                            "when it can"),
        "correct_power": Param("bool", default=True,
                               doc="keep total power (overlap-add of phase-changed frames loses 0.3-10 %) with a slow gain "
                                   "(~8 frames); exactly 1 when one axis moves"),
    }
    inputs = {"x": Port((3,), "*", "3-axis signal (e.g. acceleration), any unit")}
    outputs = {"y": Port((), "=x", "1-axis signal, same unit, delayed by frame - 1 samples")}
    latency_doc = "frame - 1 samples (127 samples = 127 ms at 1 kHz with the defaults)"
    kernel = _dft321
    memory = Memory(params=PARAMS, state=STATE, istate=ISTATE)

    def latency_samples(self) -> int:
        return latency_samples(self.p["frame"])

    def resolve(self, inputs):
        return {"y": PortSpec((), inputs["x"].unit)}

    def build(self, inputs, outputs):
        try:
            check_config(self.p["frame"], self.p["hop"], self.p["window"])
            params = stream_params(self.p["frame"], self.p["hop"], self.p["window"], self.p["correct_power"], self.p["method"])
        except ValueError as exc:
            raise ParamError(str(exc).partition(": ")[0], str(exc)) from None
        return self.pack_state(param_sizes(params), params=params)
