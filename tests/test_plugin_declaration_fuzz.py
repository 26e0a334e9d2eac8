"""Any plugin declaration either registers or is refused with one FlowtexError line: never another exception (issue 27 §5)."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

from flowtex.errors import FlowtexError
from flowtex.limits import MAX_PORT_VALUES
from flowtex.node_api import Node, Param, Port
from flowtex.nodecheck import check_node_class


@njit(cache=True)
def _kernel(p, s, si, x, y):  # pragma: no cover - compiled
    pass


sizes = st.one_of(st.integers(-3, 5), st.integers(10**4, 10**10), st.booleans(), st.floats(-2, 4), st.text(max_size=3))
shapes = st.one_of(st.none(), st.tuples(), st.tuples(sizes), st.tuples(sizes, sizes), st.text(max_size=6),
                   st.sampled_from(["=x", "=y", "=", "=nope"]), st.lists(sizes, max_size=2), st.integers(-2, 3))
units = st.one_of(st.sampled_from(["", "*", "N", "=x", "=nope", "="]), st.integers(0, 2), st.none())


@settings(max_examples=300, deadline=None)
@given(in_shape=shapes, out_shape=shapes, in_unit=units, out_unit=units)
def test_any_port_declaration_registers_or_is_refused_in_one_line(in_shape, out_shape, in_unit, out_unit):
    try:
        ports = {"inputs": {"x": Port(in_shape, in_unit)}, "outputs": {"y": Port(out_shape, out_unit)}}
    except Exception as exc:  # Port is a plain dataclass: it takes anything
        raise AssertionError(exc) from exc
    cls = type("Fuzzed", (Node,), {"type_name": "fuzzed", "kernel": _kernel, "__module__": "fuzz_plugin", **ports})
    try:
        check_node_class(cls)
    except FlowtexError as exc:
        assert "\n" not in str(exc) and "node 'fuzzed'" in str(exc)
        return
    # accepted: then every declared shape is usable by the graph checker
    for port, output in ((cls.inputs["x"], False), (cls.outputs["y"], True)):
        shape = port.shape
        if isinstance(shape, tuple):
            assert all(isinstance(n, int) and not isinstance(n, bool) and n >= 1 for n in shape)
            width = 1
            for n in shape:
                width *= n
            assert width <= MAX_PORT_VALUES
        elif isinstance(shape, str):
            assert shape == "=x"
        else:
            assert shape is None and not output


numbers = st.one_of(st.none(), st.floats(allow_nan=True), st.integers(-10, 10), st.booleans(), st.text(max_size=2))


@settings(max_examples=300, deadline=None)
@given(kind=st.sampled_from(["float", "int", "floats", "bool", "choice", "str", "nope"]), lo=numbers, hi=numbers,
       default=numbers)
def test_any_param_declaration_is_accepted_or_a_value_error(kind, lo, hi, default):
    try:
        param = Param(kind, default=default, min=lo, max=hi)
    except ValueError as exc:  # raised at the plugin's line while it is imported: 'plugin failed to load: ...'
        assert "\n" not in str(exc)
        return
    assert kind != "nope"
    if isinstance(lo, (int, float)) and isinstance(hi, (int, float)):
        assert lo <= hi  # min > max never gets through
    if default is not None:
        param.coerce(default)  # an accepted default is a valid value of its own parameter
