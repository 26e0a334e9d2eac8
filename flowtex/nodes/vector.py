"""3-vector geometry nodes: cross (a x b), dot (a . b) and normalize (x / |x| with a safe zero-length rule).

They exist for rendering forces in the tangent plane, e.g. HaTT's texture force
direction ``normalize(velocity) x normal`` (docs/texture.md). The kernels are a
few multiplications per tick and allocate nothing.
"""

from __future__ import annotations

import math

from numba import njit

from ..node_api import Field, Layout, Memory, Node, NodeState, Param, Port, PortSpec, check, unit_product

NORMALIZE = Memory(params=Layout("float", [Field("min_norm", 1, "below this magnitude the output is zero")]))
P_MIN_NORM = NORMALIZE.params.const("min_norm")


@njit(cache=True)
def _cross(p, s, si, a, b, y):
    for t in range(a.shape[0]):
        a0 = a[t, 0]
        a1 = a[t, 1]
        a2 = a[t, 2]
        b0 = b[t, 0]
        b1 = b[t, 1]
        b2 = b[t, 2]
        y[t, 0] = a1 * b2 - a2 * b1
        y[t, 1] = a2 * b0 - a0 * b2
        y[t, 2] = a0 * b1 - a1 * b0


class Cross(Node):
    """Cross product of two 3-vectors: y = a x b (right-handed; unit: product of the units)."""

    type_name = "cross"
    inputs = {"a": Port((3,), "*", "first 3-vector"), "b": Port((3,), "*", "second 3-vector")}
    outputs = {"y": Port((3,), "", "a x b", unit_doc="unit of a * unit of b")}
    kernel = _cross
    memory = Memory()

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        return {"y": PortSpec((3,), unit_product(inputs["a"].unit, inputs["b"].unit))}


@njit(cache=True)
def _dot(p, s, si, a, b, y):
    for t in range(a.shape[0]):
        acc = 0.0
        for c in range(a.shape[1]):
            acc += a[t, c] * b[t, c]
        y[t, 0] = acc


class Dot(Node):
    """Scalar product of two vectors of the same shape: y = a . b (unit: product of the units)."""

    type_name = "dot"
    inputs = {"a": Port(None, "*", "first vector"), "b": Port(None, "*", "second vector (same shape as a)")}
    outputs = {"y": Port((), "", "a . b", unit_doc="unit of a * unit of b")}
    kernel = _dot
    memory = Memory()

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        a, b = inputs["a"], inputs["b"]
        check(len(a.shape) == 1, None, f"input a must be a vector, got shape {a.shape or 'scalar'}")
        check(b.shape == a.shape, None, f"input b must have a's shape {a.shape}, got {b.shape or 'scalar'}")
        return {"y": PortSpec((), unit_product(a.unit, b.unit))}


@njit(cache=True)
def _normalize(p, s, si, x, y):
    min_norm = p[P_MIN_NORM]
    for t in range(x.shape[0]):
        acc = 0.0
        for c in range(x.shape[1]):
            acc += x[t, c] * x[t, c]
        r = math.sqrt(acc)
        # NaN/inf (anywhere in x) makes r non-finite; r <= min_norm has no direction.
        if r > min_norm and r < math.inf:
            for c in range(x.shape[1]):
                y[t, c] = x[t, c] / r
        else:
            for c in range(x.shape[1]):
                y[t, c] = 0.0


class Normalize(Node):
    """Unit vector y = x / |x|; the zero vector when |x| <= min_norm or x has NaN/inf (no direction, no force).

    The zero-vector rule keeps a direction times a magnitude silent when the
    direction is undefined (a tool at rest, a dropped sample) instead of
    dividing by zero. Large finite vectors are fine as long as |x| stays
    finite (components up to about 1e154).
    """

    type_name = "normalize"
    params = {
        "min_norm": Param("float", default=1e-9, min=0.0,
                          doc="lengths at or below this give the zero vector (unit of x, e.g. mm/s for a velocity)"),
    }
    inputs = {"x": Port(None, "*", "vector")}
    outputs = {"y": Port("=x", "", "unit vector along x, or zeros (dimensionless)")}
    kernel = _normalize
    memory = NORMALIZE

    def resolve(self, inputs: dict[str, PortSpec]) -> dict[str, PortSpec]:
        x = inputs["x"]
        check(len(x.shape) == 1, None, f"input x must be a vector, got shape {x.shape or 'scalar'}")
        return {"y": PortSpec(x.shape, "")}

    def build(self, inputs: dict[str, PortSpec], outputs: dict[str, PortSpec]) -> NodeState:
        return self.pack_state(params={"min_norm": self.p["min_norm"]})
