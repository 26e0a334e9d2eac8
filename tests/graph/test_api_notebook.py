"""The in-memory API as a notebook uses it: what a researcher hands over by mistake is refused in one line, never
used as other numbers, and a node's own refusal names the node type and the parameter.

* a masked array (``np.ma``) converted as it is keeps the values under its mask as data: refused when anything is
  masked, by ``Graph.run`` and ``Node.processor`` alike;
* 64-bit integers above 2**53 and extended floats (``np.longdouble``) become other numbers in float64: refused when
  a sample would change, accepted when every sample is exact;
* a processor's parameter refused by the node's ``resolve``/``build`` or by the file it reads (a cutoff above
  Nyquist, a missing model file) says which node type and which parameter, as a graph's message does.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from flowtex.errors import InputError, ParamError
from flowtex.graph.builder import GraphBuilder
from flowtex.pyvalues import float_signal
from flowtex.registry import load_registry


def _lowpass():
    return load_registry().types["first_order_lowpass"].processor(rate=1000.0, cutoff_hz=50.0)


@pytest.fixture(scope="module")
def gain_graph():
    return GraphBuilder("g").input("x").node("f", "gain", k=2.0).edge("x -> f.x").output("y", "f.y").build()


def test_a_masked_sample_is_refused_by_a_processor_and_a_graph_naming_the_input_and_the_fix(gain_graph):
    x = np.ma.array([1.0, 2.0, 3.0, 4.0], mask=[0, 0, 1, 0])
    for call in (lambda: _lowpass()(x=x), lambda: gain_graph.run({"x": x})):
        with pytest.raises(InputError, match=r"input 'x' is a masked array with 1 masked sample\(s\) \(the first at "
                                             r"index 2\).*x\.filled\(np\.nan\)"):
            call()


def test_a_masked_array_with_nothing_masked_runs_as_its_data(gain_graph):
    x = np.ma.array([1.0, 2.0, 3.0])
    assert np.array_equal(gain_graph.run({"x": x})["y"].ravel(), [2.0, 4.0, 6.0])


@settings(max_examples=40, deadline=None)
@given(st.lists(st.integers(-(2**63), 2**63 - 1), min_size=1, max_size=20))
def test_int64_samples_run_exactly_or_are_refused(values):
    arr = np.array(values, dtype=np.int64)
    exact = all(int(float(v)) == v for v in values)
    if exact:
        assert np.array_equal(float_signal("x", arr), np.array(values, dtype=float))
    else:
        with pytest.raises(InputError, match="input 'x' \\(dtype int64\\) holds .* float64 cannot hold exactly"):
            float_signal("x", arr)


def test_an_extended_float_that_float64_rounds_is_refused_and_an_exact_one_runs():
    with pytest.raises(InputError, match=r"dtype float128\) holds 1 sample\(s\) .*the first at index 1"):
        _lowpass()(x=np.array([1.0, 1.0, 2.0], dtype=np.longdouble) / np.array([1, 3, 1], dtype=np.longdouble))
    assert _lowpass()(x=np.arange(3, dtype=np.longdouble))["y"].dtype == np.float64


def test_a_parameter_the_node_refuses_at_build_names_the_node_type_and_the_parameter():
    lp = load_registry().types["butterworth"].processor(rate=1000.0, order=2, cutoff_hz=600.0)
    with pytest.raises(ParamError, match=r"^node type 'butterworth' processor: parameter 'cutoff_hz': cutoff 600 Hz must "
                                         r"lie between 0 and the Nyquist frequency 500 Hz") as err:
        lp(x=np.zeros(4))
    assert err.value.param == "cutoff_hz"
    with pytest.raises(ParamError, match=r"^node type 'texture_lookup' processor: parameter 'models': nowhere\.xml: "):
        load_registry().types["texture_lookup"].processor(models="nowhere.xml")


def test_an_input_connected_twice_in_the_builder_names_both_builder_calls_not_line_0():
    from flowtex.errors import GraphError

    b = GraphBuilder("g").input("x").input("z").node("f", "gain", k=1.0).edge("x -> f.x").edge("z -> f.x").output("y", "f.y")
    with pytest.raises(GraphError, match=r"^GraphBuilder.edge\('z -> f.x'\): input f.x is connected twice \(also at "
                                         r"GraphBuilder.edge\('x -> f.x'\)\); an input takes exactly one edge$"):
        b.resolve()


def test_step_given_a_list_for_a_scalar_input_says_to_pass_one_number(gain_graph):
    from flowtex.errors import FlowtexError

    with pytest.raises(FlowtexError, match=r"input 'x' is a scalar; step\(\) got \[1.0\]; pass one number, e.g. \{'x': 1.0\}"):
        gain_graph.step({"x": [1.0]})


def test_a_graph_pickled_mid_run_continues_in_the_copy_bit_for_bit():
    import pickle

    g = (GraphBuilder("lp", seed=3).input("x").node("n", "white_noise", variance=0.25).node("s", "add")
         .node("f", "first_order_lowpass", cutoff_hz=40.0).edge("x -> s.a").edge("n.y -> s.b").edge("s.y -> f.x")
         .output("y", "f.y").build())
    x = np.sin(np.arange(600) / 7.0)
    whole = g.run({"x": x})["y"]
    g.reset()
    first = g.process({"x": x[:250]})["y"]
    copy = pickle.loads(pickle.dumps(g))
    assert np.array_equal(np.concatenate([first, copy.process({"x": x[250:]})["y"]]), whole)
    assert copy.ticks == 600 and g.ticks == 250


def test_a_processor_at_another_rate_than_its_model_or_input_names_the_node_type_and_the_parameter():
    from flowtex.datasets.model_sets import cork_like_model_set

    types = load_registry().types
    with pytest.raises(ParamError, match=r"^node type 'texture_lookup' processor: parameter 'models': the model set "
                                         r"'cork-like' given in memory is for 1000 Hz but the graph runs at 2000 Hz"):
        types["texture_lookup"].processor(rate=2000.0, models=cork_like_model_set())
    with pytest.raises(ParamError, match=r"^node type 'resample' processor: parameter 'from_hz': from_hz is 1000 Hz but "
                                         r"input 'x' arrives at 2000 Hz"):
        types["resample"].processor(rate=2000.0, from_hz=1000.0, to_hz=500.0)


def test_the_builder_refuses_a_base_dir_that_is_no_path_and_block_rows_0_instead_of_ignoring_it():
    from flowtex.errors import GraphError

    with pytest.raises(GraphError, match=r"^GraphBuilder\('g'\): base_dir must be a folder path \(str or pathlib.Path\), got 5$"):
        GraphBuilder("g", base_dir=5)
    with pytest.raises(InputError, match=r"block_rows must be an integer >= 1, got 0"):
        GraphBuilder("g").input("x").output("y", "x").build(block_rows=0)


def _raising_node(raised: Exception):
    """A node type whose build() raises ``raised``, as a plugin written in a notebook might (built-in ``gain``'s
    ports and kernel, defined outside flowtex)."""
    gain = load_registry().types["gain"]

    class Raising(gain):
        """Raises in build."""

        type_name = "raising_build"

        def build(self, inputs, outputs):
            raise raised

    return Raising


def test_a_plugin_build_that_raises_is_reported_at_its_line_and_a_data_error_subclass_keeps_its_message():
    from flowtex.errors import DataError, FlowtexError

    class OddDataError(DataError):
        def __init__(self, path, reason):
            super().__init__(f"{path}: {reason}")

    with pytest.raises(DataError, match=r"^node type 'raising_build' processor: table.csv: no header$"):
        _raising_node(OddDataError("table.csv", "no header")).processor(k=1.0)(x=np.zeros(2))
    with pytest.raises(FlowtexError, match=r"build\(\) of graph node 'raising_build' raised KeyError: 'gain'"):
        _raising_node(KeyError("gain")).processor(k=1.0)(x=np.zeros(2))


@pytest.mark.parametrize("path", [5, None, b"graph.yaml"])
def test_load_graph_given_no_path_says_so_in_one_graph_error(path):
    import flowtex
    from flowtex.errors import GraphError

    with pytest.raises(GraphError, match=r"a graph file is named by a path \(str or pathlib.Path\), got "):
        flowtex.load_graph(path)


@pytest.mark.parametrize(("edge", "message"), [
    ("x -> f.xx", "edge 'x -> f.xx': node 'f' (gain) has no input 'xx' (did you mean 'x'?); its inputs are: x"),
    ("x -> ff.x", "edge 'x -> ff.x': no node 'ff' (did you mean 'f'?)"),
])
def test_a_misspelt_input_port_or_node_is_one_error_not_a_second_one_for_the_input_it_meant(edge, message):
    from flowtex.errors import GraphError

    b = GraphBuilder("g").input("x").node("f", "gain", k=1.0).edge(edge).output("y", "f.y")
    with pytest.raises(GraphError) as err:
        b.resolve()
    assert [d.message for d in err.value.diagnostics] == [message]


def test_a_refused_call_leaves_the_value_a_hold_processor_holds_as_it_was():
    add = load_registry().types["add"].processor(nonfinite="hold")
    add(a=np.array([1.0]), b=np.array([0.0]))
    with pytest.raises(InputError, match="inputs have different numbers of ticks"):
        add(a=np.array([7.0]), b=np.array([1.0, 2.0]))  # refused: its 7.0 must not become the held value
    assert add(a=np.array([np.nan]), b=np.array([0.0]))["y"].ravel().tolist() == [1.0]


@pytest.mark.parametrize(("keyword", "setting"), [("rat", "rate"), ("sed", "seed"), ("nonfinit", "nonfinite"),
                                                  ("evry", "every"), ("input_evry", "input_every")])
def test_a_misspelt_processor_setting_is_named_as_the_setting_not_as_an_unknown_node_parameter(keyword, setting):
    with pytest.raises(ParamError, match=rf"^node type 'butterworth' processor: '{keyword}' is neither a parameter nor a "
                                         rf"setting \(did you mean the setting '{setting}'\?\); settings: rate, seed"):
        load_registry().types["butterworth"].processor(order=2, cutoff_hz=10.0, **{keyword: 1})


def test_a_misspelt_every_in_the_builder_is_named_as_every():
    from flowtex.errors import GraphError

    with pytest.raises(GraphError, match=r"^GraphBuilder.node\('a', 'gain', evry=...\): node 'a' \(gain\): 'evry' is no "
                                         r"parameter of 'gain'; did you mean every=4 \(run the node every k ticks\)\?$"):
        GraphBuilder("g").input("x").node("a", "gain", k=1.0, evry=4)


def test_a_transposed_vector_input_is_named_with_the_transpose_as_the_fix():
    g = GraphBuilder("v").input("p", shape=(3,)).node("n", "norm").edge("p -> n.x").output("y", "n.y").build()
    with pytest.raises(InputError, match=r"^input 'p': expected shape \(n, 3\) with time first, got \(3, 10\); pass its "
                                         r"transpose \(x.T\): time goes first$"):
        g.run({"p": np.ones((3, 10))})
