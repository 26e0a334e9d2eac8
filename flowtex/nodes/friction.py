"""Friction nodes: coulomb_friction (HaTT's viscous/Coulomb rule) and dahl_friction (stick-slip).

Sources: Kuchenbecker & Culbertson 2014, "Haptic rendering of textures" (tutorial);
Culbertson & Kuchenbecker 2017, "Importance of matching physical friction, hardness, and texture
in creating realistic haptic virtual surfaces" (Dahl model, section 3.3.1).

Both output a tangential force 3-vector (N) opposing the motion; the math and
its NaN policy live in flowtex.dsp.friction, the reasoning in docs/friction.md.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from ..dsp.friction import (
    COULOMB_P,
    DAHL_P,
    DAHL_S,
    DAHL_SI,
    DAHL_STATE,
    DS_NORMAL,
    coulomb_block,
    coulomb_threshold,
    dahl_block,
)
from ..dsp.motion import initial_normal_state
from ..errors import ParamError
from ..models.texture import TextureModelSet
from ..node_api import Memory, Node, NodeState, Param, Port, check
from .texture import model_source

DAHL_ZMAX_PER_MU_MM = 4.0
"""Culbertson & Kuchenbecker 2017: z_max = 4 mm * mu_k."""


def _mu_or_models(params: dict[str, Any]) -> None:
    """``mu`` and ``models`` exclude each other (checked before the model file is read)."""
    if params["mu"] is not None and params.get("models") is not None:
        raise ParamError("models", "give either mu or models, not both")


def _mu(node: Node) -> float:
    """Friction coefficient from ``mu`` or from the model set given as ``models`` (read by the graph/io boundary)."""
    mu, ms = node.p["mu"], node.p.get("models")
    if ms is not None:
        mu = ms.mu
        if mu is None or not math.isfinite(mu) or mu < 0:
            raise ParamError("models", f"{model_source(ms, node.context.files.get('models'))}: the model set has no usable "
                                       f"friction coefficient (mu = {mu!r}); give mu instead (on the command line: "
                                       f"--set {node.name}.models=null --set {node.name}.mu=0.3), or fit one into the set "
                                       "(flowtex fit friction REC ... --into SET)")
        return float(mu)
    if mu is None:
        raise ParamError("mu", "missing friction coefficient: give mu (e.g. mu: 0.3) or models (a model set file)")
    return float(mu)


@njit(cache=True)
def _coulomb(p, s, si, velocity, normal_force, force):
    coulomb_block(p, velocity, normal_force, force)


class CoulombFriction(Node):
    """Kinetic friction F = -mu F_n 0.004 v below a threshold speed, -mu F_n v/|v| above (HaTT's rule, Kuchenbecker & Culbertson 2014).

    mode ``continuous`` (default) puts the threshold at 1/0.004 = 250 mm/s
    where both branches meet; ``hatt`` uses HaTT's mu/0.004 mm/s, with its
    jump from mu^2 F_n to mu F_n. NaN velocity or force gives zero force.
    """

    type_name = "coulomb_friction"
    params = {
        "mu": Param("float", default=None, min=0.0, doc="kinetic friction coefficient mu_k (or give models)"),
        "models": Param("path", default=None, objects=(TextureModelSet,),
                        doc="model set file whose friction coefficient is used instead of mu"),
        "mode": Param("choice", default="continuous", choices=("continuous", "hatt"), doc="threshold rule (see summary)"),
    }
    inputs = {"velocity": Port((3,), "mm/s", "tangential velocity"), "normal_force": Port((), "N", "normal force (< 0 counts as 0)")}
    outputs = {"force": Port((3,), "N", "friction force on the tool")}
    kernel = _coulomb
    check_params = staticmethod(_mu_or_models)
    memory = Memory(params=COULOMB_P)

    def build(self, inputs, outputs):
        mu = _mu(self)
        return NodeState(params=COULOMB_P.pack({"mu": mu, "threshold": coulomb_threshold(mu, self.p["mode"])}))


@njit(cache=True)
def _dahl(p, s, si, position, normal_force, normal, force):
    dahl_block(p, s, si, position, normal_force, normal, force)


class DahlFriction(Node):
    """Dahl stick-slip friction (Culbertson & Kuchenbecker 2017) in the tangent plane: spring of stretch z <= z_max to an adhesion point.

    F = -mu F_n z / z_max; the adhesion point is dragged along once the tool
    is z_max away. When F_n rises the spring is shortened so its stored
    energy never grows (passive; docs/friction.md).
    """

    type_name = "dahl_friction"
    params = {
        "mu": Param("float", default=None, min=0.0, doc="kinetic friction coefficient mu_k (or give models)"),
        "models": Param("path", default=None, objects=(TextureModelSet,),
                        doc="model set file whose friction coefficient is used instead of mu"),
        "z_max": Param("float", default=None, unit="mm", min=0.0, min_exclusive=True,
                       doc="largest spring stretch; default 4 mm * mu (Culbertson & Kuchenbecker 2017)"),
        "normal": Param("floats", default=(0.0, 0.0, 1.0), length=(3, 3), doc="surface normal when the normal input is not connected"),
    }
    inputs = {
        "position": Port((3,), "mm", "tool position"),
        "normal_force": Port((), "N", "normal force (< 0 counts as 0)"),
        "normal": Port((3,), "", "surface normal (normalised; zero/NaN keeps the last valid one)", optional=True),
    }
    outputs = {"force": Port((3,), "N", "friction force on the tool")}
    kernel = _dahl
    check_params = staticmethod(_mu_or_models)
    memory = Memory(params=DAHL_P, state=DAHL_S, istate=DAHL_SI)

    def input_default(self, name, spec):
        return np.asarray(self.p["normal"], dtype=np.float64)

    def build(self, inputs, outputs):
        check(math.hypot(*self.p["normal"]) > 1e-9, "normal", f"the normal {list(self.p['normal'])} has zero length")
        mu = _mu(self)
        z_max = self.p["z_max"]
        if z_max is None:
            z_max = DAHL_ZMAX_PER_MU_MM * mu
            if z_max <= 0.0:
                z_max = 1.0  # mu = 0: no force whatever z_max is
        return NodeState(params=DAHL_P.pack({"mu": mu, "z_max": z_max}),
                         state=initial_normal_state(DAHL_STATE, DS_NORMAL, self.p["normal"]),
                         istate=DAHL_SI.zeros())
