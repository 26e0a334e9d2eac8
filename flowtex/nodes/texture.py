"""Texture-model lookup: (speed, force) -> the interpolated ARMA model of a HaTT or native model set."""

from __future__ import annotations

from pathlib import Path

from numba import njit

from ..dsp.interp import ISTATE, STATE, TABLE, initial_state, table_sizes, texture_lookup_block
from ..errors import ParamError
from ..models.outside import OUTSIDE_CHOICES
from ..models.rendering import INTERPOLATION_CHOICES, texture_table
from ..models.texture import TextureModelSet
from ..node_api import Memory, Node, Param, Port, PortSpec


@njit(cache=True)
def _texture_lookup(p, s, si, speed, force, ar, ma, gain, variance):
    texture_lookup_block(p, s, si, speed, force, ar, ma, gain, variance)


def model_source(ms: TextureModelSet, file: Path | None) -> str:
    """How messages name a ``models`` parameter: the file it was read from, or the in-memory set's name."""
    if file is None:
        return f"the model set {ms.material!r} given in memory"
    return str(file)


def rate_mismatch_message(path: str, ms: TextureModelSet, graph_rate: float) -> str:
    """One line refusing a model set at another rate: the file's own field (XML tag or JSON key) and the fix."""
    import shlex

    field = "<SampleRate>" if str(path).lower().endswith(".xml") else '"sample_rate"'
    return (f"{path}: the models are for {ms.sample_rate:g} Hz ({field}) but the graph runs at {graph_rate:g} Hz; "
            f"run 'flowtex models resample {shlex.quote(str(path))} --rate {graph_rate:g} -o OUT.json' and load OUT.json, "
            f"or run the graph at the models' rate (--set rate={ms.sample_rate:g})")


class TextureLookup(Node):
    """Interpolate a texture model set at the current (speed, force): AR and MA polynomials, gain and excitation variance.

    Barycentric interpolation of line spectral frequencies in the Delaunay
    triangle containing the (clamped) query, as HaTT's renderer does, but in
    float64 and with a bounded point location that never loops. Queries
    outside the triangulation's hull (after clamping) use the nearest point of
    the hull (distance measured in units of max speed and max force). NaN in
    either input holds the last model; before the first valid input the model
    is silent (A = C = 1, gain 0, variance 0). The set's rendering rule
    (``interpolation``, ``outside``) comes from the file, HaTT's when it states
    none; the node's parameters override it (flowtex.models.rendering,
    docs/texture.md).
    """

    type_name = "texture_lookup"
    params = {
        "models": Param("path", objects=(TextureModelSet,),
                        doc="texture model set: a HaTT Models_<name>.xml file or a flowtex JSON model set"),
        "low_speed": Param("float", default=0.05, unit="mm/s", min=0.0, doc="speeds below this are replaced by low_speed_value (HaTT: 0.05)"),
        "low_speed_value": Param("float", default=0.0001, unit="mm/s", min=0.0, doc="speed used below low_speed (HaTT: 0.0001)"),
        "speed_margin": Param("float", default=0.01, unit="mm/s", min=0.0,
                              doc="speeds above the set's maxSpeed become maxSpeed - speed_margin (HaTT: 0.01)"),
        "low_force": Param("float", default=0.05, unit="N", min=0.0, doc="forces below this are replaced by low_force_value (HaTT: 0.05)"),
        "low_force_value": Param("float", default=0.0001, unit="N", min=0.0, doc="force used below low_force (HaTT: 0.0001)"),
        "force_margin": Param("float", default=0.01, unit="N", min=0.0,
                              doc="forces above the set's maxForce become maxForce - force_margin (HaTT: 0.01)"),
        "outside": Param("choice", default=None, choices=OUTSIDE_CHOICES,
                         doc="beyond the measured models (default: the model set's rule, HaTT's fade for a HaTT file or "
                             "a set that states none): fade (HaTT: silent corners, linear fade below the slowest speed, "
                             "saturation at the maximum), hold (nearest models as they are) or trend (nearest models' "
                             "spectrum, power along the set's own power law in speed and force); hold and trend are "
                             "silent below low_speed / low_force"),
        "interpolation": Param("choice", default=None, choices=INTERPOLATION_CHOICES,
                               doc="how loudness is blended between models (default: the model set's rule, HaTT's variance "
                                   "for a HaTT file or a set that states none): variance (HaTT: excitation variance, "
                                   "linearly), power (output power, linearly) or log_power (output power, geometrically); "
                                   "the spectrum is always blended by LSFs"),
        "order": Param("floats", default=None, length=(2, 2),
                       doc="[p, q]: render lower orders (Levinson step-down of each model, output power kept; "
                           "flowtex.dsp.order); default: the set's own"),
    }
    inputs = {
        "speed": Port((), "mm/s", "tangential speed of the tool"),
        "force": Port((), "N", "normal force"),
    }
    outputs = {
        "ar": Port((1,), "", "A(z) = [1, a1, ..., ap]", shape_doc="vector of p+1 (AR order p of the model file)"),
        "ma": Port((1,), "", "C(z) = [1, c1, ..., cq]", shape_doc="vector of q+1 (MA order q of the model file)"),
        "gain": Port((), "", "MA gain g"),
        "variance": Port((), "", "variance of the white excitation (HaTT's var)"),
    }
    kernel = _texture_lookup
    memory = Memory(params=TABLE, state=STATE, istate=ISTATE)

    def __init__(self, name, params, context):
        super().__init__(name, params, context)
        file = context.files.get("models")
        self.model_set: TextureModelSet = params["models"]
        self.source = model_source(self.model_set, file)
        if p_order := params.get("order"):
            self.model_set = self._truncated(p_order)
        ms = self.model_set
        if ms.sample_rate != context.rate:
            if file is None:
                raise ParamError("models", f"{self.source} is for {ms.sample_rate:g} Hz but the graph runs at {context.rate:g} Hz; "
                                           "resample it (flowtex.fit.resample.resample_model_set) or build the graph at its rate")
            raise ParamError("models", rate_mismatch_message(str(file), ms, context.rate))
        p = self.p
        for low, value in (("low_speed", "low_speed_value"), ("low_force", "low_force_value")):
            if p[value] > p[low]:
                raise ParamError(value, f"{value} ({p[value]:g}) must not exceed {low} ({p[low]:g})")
        if p["speed_margin"] >= ms.max_speed:
            raise ParamError("speed_margin", f"speed_margin ({p['speed_margin']:g}) must be below the set's max speed {ms.max_speed:g} mm/s")
        if p["force_margin"] >= ms.max_force:
            raise ParamError("force_margin", f"force_margin ({p['force_margin']:g}) must be below the set's max force {ms.max_force:g} N")

    def _truncated(self, order) -> TextureModelSet:
        import dataclasses

        from ..dsp.order import truncate_models

        ms = self.model_set
        p, q = (int(x) for x in order)
        if [p, q] != list(order) or not (1 <= p <= ms.ar_order and 1 <= q <= ms.ma_order):
            raise ParamError("order", f"order must be two integers [p, q] with 1 <= p <= {ms.ar_order} and 1 <= q <= {ms.ma_order} "
                                      f"(the set's orders), got {list(order)}")
        if (p, q) == (ms.ar_order, ms.ma_order):
            return ms
        try:
            ar, ma, var = truncate_models(ms.ar_lsf, ms.ma_lsf, ms.variance, ms.gain, p, q)
        except ValueError as exc:
            raise ParamError("order", f"{self.source}: cannot reduce the order: {exc}") from None
        return dataclasses.replace(ms, ar_lsf=ar, ma_lsf=ma, variance=var, ar_coeff=None, ma_coeff=None)

    def resolve(self, inputs):
        ms = self.model_set
        return {
            "ar": PortSpec((ms.ar_order + 1,), ""),
            "ma": PortSpec((ms.ma_order + 1,), ""),
            "gain": PortSpec((), ""),
            "variance": PortSpec((), ""),
        }

    def build(self, inputs, outputs):
        ms = self.model_set
        p = self.p
        try:
            table = texture_table(ms, p["interpolation"], p["outside"],
                                  speed_margin=p["speed_margin"], low_speed=p["low_speed"], low_speed_value=p["low_speed_value"],
                                  force_margin=p["force_margin"], low_force=p["low_force"], low_force_value=p["low_force_value"])
        except ValueError as exc:
            raise ParamError("models", f"{self.source}: {exc}") from None
        s, si = initial_state(ms.ar_order, ms.ma_order)
        return self.pack_state(table_sizes(table), params=table, state=s, istate=si)

