"""Motion nodes: speed_estimator (tangential speed and velocity) and contact (hysteresis, onset, incoming speed)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from ..dsp.contact import CONTACT_OFF_N, CONTACT_ON_N, DEFAULT_CUTOFF_HZ, HATT_CORNER_RAD_S, STATIONARY_MM
from ..dsp.motion import (
    CONTACT_P,
    CONTACT_S,
    CONTACT_SI,
    CONTACT_STATE,
    CS_NORMAL,
    SPEED_P,
    SPEED_S,
    SPEED_SI,
    SPEED_STATE,
    SS_NORMAL,
    butter2_biquad,
    contact_block,
    first_order_biquad,
    initial_normal_state,
    speed_block,
    speed_params,
)
from ..errors import ParamError
from ..node_api import Memory, Node, NodeState, Param, Port, check

_NORMAL_PARAM = Param("floats", default=(0.0, 0.0, 1.0), length=(3, 3),
                      doc="surface normal used when the normal input is not connected (normalised; need not be unit)")
_NORMAL_PORT = Port((3,), "", "surface normal (normalised; a zero/NaN normal keeps the last valid one)", optional=True)


def _check_normal(normal: tuple[float, ...]) -> None:
    check(math.hypot(*normal) > 1e-9, "normal", f"the normal {list(normal)} has zero length; give a direction such as [0, 0, 1]")


@njit(cache=True)
def _speed(p, s, si, position, normal, speed, velocity):
    speed_block(p, s, si, position, normal, speed, velocity)


class SpeedEstimator(Node):
    """Tangential tool speed and velocity (mm/s) from position (mm): backward difference, low-pass, projection, stationary gate.

    ``lowpass``: first-order low-pass at ``cutoff_hz`` (20 Hz as in HaTT and Romano & Kuchenbecker 2012).
    ``hatt``: 2nd-order Butterworth at 125 rad/s (bilinear, pre-warped). The
    stationary gate (Romano & Kuchenbecker 2012, section 4.1) zeroes the outputs while the 10 Hz high-passed,
    100 Hz low-passed tangential displacement is shorter than ``stationary_mm``.
    NaN/inf positions are skipped (outputs hold); see flowtex.dsp.motion.
    """

    type_name = "speed_estimator"
    params = {
        "method": Param("choice", default="lowpass", choices=("lowpass", "hatt"), doc="velocity filter"),
        "cutoff_hz": Param("float", default=None, unit="Hz", min=0.0, min_exclusive=True,
                           doc="corner of the lowpass method (default 20 Hz); not used by hatt"),
        "stationary_mm": Param("float", default=STATIONARY_MM, unit="mm", min=0.0,
                               doc="stationary threshold on the filtered displacement (Romano & Kuchenbecker 2012); 0 disables it"),
        "normal": _NORMAL_PARAM,
    }
    inputs = {"position": Port((3,), "mm", "tool position"), "normal": _NORMAL_PORT}
    outputs = {"speed": Port((), "mm/s", "tangential speed |v_t|"), "velocity": Port((3,), "mm/s", "tangential velocity v_t")}
    kernel = _speed
    memory = Memory(params=SPEED_P, state=SPEED_S, istate=SPEED_SI)

    def input_default(self, name, spec):
        return np.asarray(self.p["normal"], dtype=np.float64)

    def build(self, inputs, outputs):
        _check_normal(self.p["normal"])
        rate = self.context.node_rate
        cutoff = self.p["cutoff_hz"]
        if self.p["method"] == "lowpass":
            cutoff = DEFAULT_CUTOFF_HZ if cutoff is None else cutoff
            if cutoff >= rate / 2:
                raise ParamError("cutoff_hz", f"cutoff {cutoff:g} Hz must be below Nyquist ({rate / 2:g} Hz)")
            biquad = first_order_biquad(cutoff, rate)
        else:
            if cutoff is not None:
                raise ParamError("cutoff_hz", "method hatt has a fixed 125 rad/s corner; remove cutoff_hz or use method: lowpass")
            try:
                biquad = butter2_biquad(HATT_CORNER_RAD_S, rate)
            except ValueError as exc:
                raise ParamError("method", f"hatt filter at node rate {rate:g} Hz: {exc}") from None
        return NodeState(params=speed_params(biquad, rate, self.p["stationary_mm"]),
                         state=initial_normal_state(SPEED_STATE, SS_NORMAL, self.p["normal"]),
                         istate=SPEED_SI.zeros())


@njit(cache=True)
def _contact(p, s, si, normal_force, position, normal, in_contact, incoming_speed, onset):
    contact_block(p, s, si, normal_force, position, normal, in_contact, incoming_speed, onset)


class Contact(Node):
    """Contact detection with force hysteresis: in_contact (0/1), onset pulse, incoming normal speed (mm/s) held while in contact.

    Contact begins when normal_force >= on_n and ends when it falls below
    off_n. incoming_speed is the approach speed -(v . n) of the backward
    difference velocity at the onset tick (clamped at 0), held until release.
    """

    type_name = "contact"
    params = {
        "on_n": Param("float", default=CONTACT_ON_N, unit="N", min=0.0, doc="force at or above which contact begins"),
        "off_n": Param("float", default=CONTACT_OFF_N, unit="N", min=0.0, doc="force below which contact ends (<= on_n)"),
        "normal": _NORMAL_PARAM,
    }
    inputs = {
        "normal_force": Port((), "N", "normal force"),
        "position": Port((3,), "mm", "tool position"),
        "normal": _NORMAL_PORT,
    }
    outputs = {
        "in_contact": Port((), "", "1 while in contact, else 0"),
        "incoming_speed": Port((), "mm/s", "approach speed at the onset, held while in contact; 0 out of contact"),
        "onset": Port((), "", "1 on the tick contact begins, else 0"),
    }
    kernel = _contact
    memory = Memory(params=CONTACT_P, state=CONTACT_S, istate=CONTACT_SI)

    def input_default(self, name, spec):
        return np.asarray(self.p["normal"], dtype=np.float64)

    def build(self, inputs, outputs):
        _check_normal(self.p["normal"])
        check(self.p["off_n"] <= self.p["on_n"], "off_n", f"off_n ({self.p['off_n']:g} N) must be <= on_n ({self.p['on_n']:g} N)")
        return NodeState(params=CONTACT_P.pack({"rate": self.context.node_rate, "on": self.p["on_n"], "off": self.p["off_n"]}),
                         state=initial_normal_state(CONTACT_STATE, CS_NORMAL, self.p["normal"]),
                         istate=CONTACT_SI.zeros())
