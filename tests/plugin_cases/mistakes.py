import numpy as np
from numba import njit

from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def alloc_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        tmp = np.empty(x.shape[1])
        for c in range(x.shape[1]):
            tmp[c] = x[t, c] * p[0]
        for c in range(x.shape[1]):
            y[t, c] = tmp[c]


class Alloc(Node):
    """allocates"""
    type_name = "alloc_pc"
    params = {"k": Param("float", default=1.0)}
    inputs = {"x": Port(None, "*")}
    outputs = {"y": Port("=x", "=x")}
    kernel = alloc_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["k"]]))


@njit(cache=True)
def forget_kernel(p, s, si, x, y):
    acc = s[0]
    for t in range(x.shape[0]):
        acc = acc + p[0] * (x[t, 0] - acc)
        y[t, 0] = acc


class Forget(Node):
    """forgets its state"""
    type_name = "forget_pc"
    params = {"a": Param("float", default=0.1, min=0.0, max=1.0)}
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = forget_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([self.p["a"]]), state=np.zeros(1))


@njit(cache=True)
def col0_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0]


class Col0(Node):
    """writes column 0 only"""
    type_name = "col0_pc"
    inputs = {"x": Port((3,), "*")}
    outputs = {"y": Port((3,), "=x")}
    kernel = col0_kernel


@njit(cache=True)
def oob_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0]
        s[t + 100000] = 1.0


class Oob(Node):
    """writes out of bounds"""
    type_name = "oob_pc"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = oob_kernel

    def build(self, inputs, outputs):
        return NodeState(state=np.zeros(1))
