"""Arithmetic and vector nodes: constant, gain, add, subtract, multiply, clip, norm, select."""

from __future__ import annotations

import numpy as np
from numba import njit

from ..node_api import Field, Layout, Memory, Node, Param, Port, PortSpec, check, unit_product

CONSTANT = Memory(params=Layout("float", [Field("value", "w", "the value, one per component")], sizes=("w",)))
P_VALUE = CONSTANT.params.const("value")
GAIN = Memory(params=Layout("float", [Field("k", 1, "gain factor")]))
P_K = GAIN.params.const("k")
CLIP = Memory(params=Layout("float", [Field("low", 1), Field("high", 1), Field("nan", 1, "value replacing NaN")]))
P_LOW = CLIP.params.const("low")
P_HIGH = CLIP.params.const("high")
P_NAN = CLIP.params.const("nan")
SELECT = Memory(params=Layout("float", [Field("index", 1, "0-based component")]))
P_INDEX = SELECT.params.const("index")
STATELESS = Memory()
"""Nodes without parameters or state in their arrays."""


@njit(cache=True)
def _constant(p, s, si, y):
    for t in range(y.shape[0]):
        for c in range(y.shape[1]):
            y[t, c] = p[P_VALUE + c]


class Constant(Node):
    """Output a fixed value (scalar or vector) every tick."""

    type_name = "constant"
    params = {
        "value": Param("floats", doc="the value; a list gives a vector output", length=(1, 64)),
        "unit": Param("str", default="-", doc="unit of the output ('-' for dimensionless)"),
        "vector": Param("bool", default=False, doc="make a one-element list a 1-vector instead of a scalar"),
    }
    outputs = {"y": Port((), "", "the value", shape_doc="scalar, or vector of the values", unit_doc="the 'unit' parameter")}
    kernel = _constant
    memory = CONSTANT

    def resolve(self, inputs):
        values = self.p["value"]
        shape = (len(values),) if (len(values) > 1 or self.p["vector"]) else ()
        return {"y": PortSpec(shape, "" if self.p["unit"] == "-" else self.p["unit"])}

    def build(self, inputs, outputs):
        return self.pack_state({"w": len(self.p["value"])}, params={"value": self.p["value"]})


@njit(cache=True)
def _gain(p, s, si, x, y):
    k = p[P_K]
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            y[t, c] = k * x[t, c]


class Gain(Node):
    """Multiply by a constant: y = k * x (scalar or vector x)."""

    type_name = "gain"
    params = {
        "k": Param("float", doc="gain factor"),
        "unit": Param("str", default="=", doc="unit of y; '=' keeps the unit of x"),
    }
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "k * x", unit_doc="the 'unit' parameter, or unit of x")}
    kernel = _gain
    memory = GAIN

    def resolve(self, inputs):
        unit = inputs["x"].unit if self.p["unit"] == "=" else ("" if self.p["unit"] == "-" else self.p["unit"])
        return {"y": PortSpec(inputs["x"].shape, unit)}

    def build(self, inputs, outputs):
        return self.pack_state(params={"k": self.p["k"]})


@njit(cache=True)
def _add(p, s, si, a, b, y):
    for t in range(a.shape[0]):
        for c in range(a.shape[1]):
            y[t, c] = a[t, c] + b[t, c]


@njit(cache=True)
def _subtract(p, s, si, a, b, y):
    for t in range(a.shape[0]):
        for c in range(a.shape[1]):
            y[t, c] = a[t, c] - b[t, c]


class Add(Node):
    """Element-wise sum y = a + b (same shape and unit)."""

    type_name = "add"
    inputs = {"a": Port(None, "*", "first term"), "b": Port("=a", "=a", "second term")}
    outputs = {"y": Port("=a", "=a", "a + b")}
    kernel = _add
    memory = STATELESS


class Subtract(Node):
    """Element-wise difference y = a - b (same shape and unit)."""

    type_name = "subtract"
    inputs = {"a": Port(None, "*", "minuend"), "b": Port("=a", "=a", "subtrahend")}
    outputs = {"y": Port("=a", "=a", "a - b")}
    kernel = _subtract
    memory = STATELESS


@njit(cache=True)
def _multiply(p, s, si, a, b, y):
    wb = b.shape[1]
    for t in range(a.shape[0]):
        for c in range(a.shape[1]):
            y[t, c] = a[t, c] * b[t, c if wb > 1 else 0]



class Multiply(Node):
    """Element-wise product y = a * b; b may be a scalar that scales a vector a."""

    type_name = "multiply"
    inputs = {"a": Port(None, "*", "first factor"), "b": Port(None, "*", "second factor (same shape as a, or scalar)")}
    outputs = {"y": Port("=a", "", "a * b", unit_doc="unit of a * unit of b")}
    kernel = _multiply
    memory = STATELESS

    def resolve(self, inputs):
        a, b = inputs["a"], inputs["b"]
        check(b.shape in ((), a.shape), None, f"input b must be a scalar or have a's shape {a.shape}, got {b.shape}")
        return {"y": PortSpec(a.shape, unit_product(a.unit, b.unit))}


@njit(cache=True)
def _clip(p, s, si, x, y):
    lo = p[P_LOW]
    hi = p[P_HIGH]
    for t in range(x.shape[0]):
        for c in range(x.shape[1]):
            v = x[t, c]
            if v != v:
                v = p[P_NAN]
            y[t, c] = lo if v < lo else (hi if v > hi else v)


class Clip(Node):
    """Limit every element to [low, high]; NaN becomes the value of ``nan``."""

    type_name = "clip"
    params = {
        "low": Param("float", doc="lower limit (unit of x)"),
        "high": Param("float", doc="upper limit (unit of x)"),
        "nan": Param("float", default=0.0, doc="value that replaces NaN before clipping"),
    }
    inputs = {"x": Port(None, "*", "signal")}
    outputs = {"y": Port("=x", "=x", "clipped signal")}
    kernel = _clip
    memory = CLIP

    def resolve(self, inputs):
        check(self.p["low"] <= self.p["high"], "high", f"high ({self.p['high']:g}) must be >= low ({self.p['low']:g})")
        return super().resolve(inputs)

    def build(self, inputs, outputs):
        return self.pack_state(params={"low": self.p["low"], "high": self.p["high"], "nan": self.p["nan"]})


@njit(cache=True)
def _norm(p, s, si, x, y):
    for t in range(x.shape[0]):
        acc = 0.0
        for c in range(x.shape[1]):
            acc += x[t, c] * x[t, c]
        y[t, 0] = np.sqrt(acc)


class Norm(Node):
    """Euclidean magnitude of a vector: y = |x|."""

    type_name = "norm"
    inputs = {"x": Port(None, "*", "vector")}
    outputs = {"y": Port((), "=x", "magnitude")}
    kernel = _norm
    memory = STATELESS


@njit(cache=True)
def _select(p, s, si, x, y):
    k = int(p[P_INDEX])
    for t in range(x.shape[0]):
        y[t, 0] = x[t, k]


class Select(Node):
    """One component of a vector: y = x[index]."""

    type_name = "select"
    params = {"index": Param("int", doc="0-based component index", min=0)}
    inputs = {"x": Port(None, "*", "vector")}
    outputs = {"y": Port((), "=x", "the component")}
    kernel = _select
    memory = SELECT

    def resolve(self, inputs):
        width = inputs["x"].width
        check(len(inputs["x"].shape) == 1, None, f"input x must be a vector, got shape {inputs['x'].shape}")
        check(self.p["index"] < width, "index", f"index {self.p['index']} is out of range for a {width}-vector (0..{width - 1})")
        return super().resolve(inputs)

    def build(self, inputs, outputs):
        return self.pack_state(params={"index": float(self.p["index"])})
