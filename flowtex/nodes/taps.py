"""tap_player: speed-dependent tapping transients played as a force from each contact onset.

Source: Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces", section 3.3.2.
"""

from __future__ import annotations

import shlex

from numba import njit

from ..dsp.taps import TAP_P, TAP_S, TAP_SI, initial_tap_state, tap_block, tap_params
from ..errors import ParamError
from ..models.taps import TapLibrary
from ..node_api import Memory, Node, Param, Port

HAND_MASS_KG = 0.05
"""Effective mass of hand + handle (Kuchenbecker & Culbertson 2014; Culbertson & Kuchenbecker 2017)."""


@njit(cache=True)
def _taps(p, s, si, in_contact, incoming_speed, force):
    tap_block(p, s, si, in_contact, incoming_speed, force)


class TapPlayer(Node):
    """Tap transient F = m a(t; v_in) (N) started on each rising edge of in_contact, interpolated by incoming speed.

    Below the slowest recorded tap the slowest transient is scaled by
    v_in / v_min, above the fastest the fastest is played, in between the two
    bounding transients are mixed linearly in speed. Playback lasts one
    transient (about 100 ms) and restarts on a new contact.
    """

    type_name = "tap_player"
    params = {
        "library": Param("path", objects=(TapLibrary,), doc="tap library file (docs/tap-library.md); relative to the graph file"),
        "mass": Param("float", default=HAND_MASS_KG, unit="kg", min=0.0, doc="effective mass m of hand + handle"),
    }
    inputs = {
        "in_contact": Port((), "", "contact state 0/1 (a rising edge starts a tap)"),
        "incoming_speed": Port((), "mm/s", "incoming speed, read on the onset tick"),
    }
    outputs = {"force": Port((), "N", "tap transient force")}
    kernel = _taps
    memory = Memory(params=TAP_P, state=TAP_S, istate=TAP_SI)

    def build(self, inputs, outputs):
        lib: TapLibrary = self.p["library"]
        rate = self.context.node_rate
        if abs(lib.sample_rate_hz - rate) > 1e-9 * rate:
            path = self.context.files.get("library")
            if path is None:
                raise ParamError("library", f"the tap library given in memory is sampled at {lib.sample_rate_hz:g} Hz but this node "
                                 f"runs at {rate:g} Hz; resample it (flowtex.models.taps.resample_tap_library) or run the node "
                                 "at the library's rate")
            raise ParamError("library", f"{path}: tap library is sampled at {lib.sample_rate_hz:g} Hz but this node runs at {rate:g} Hz; "
                             f"run 'flowtex models resample {shlex.quote(str(path))} --rate {rate:g} -o OUT.json' and load OUT.json, "
                             f"or run the node at the library's rate")
        s, si = initial_tap_state(lib.length)
        return self.pack_state({"k": len(lib.speeds), "length": lib.length},
                               params=tap_params(self.p["mass"], lib.speeds, lib.transients), state=s, istate=si)
