"""The Python graph API (GraphBuilder, Graph.run/process/run_ticks) given what Python code gets wrong.

Each mistake is one flowtex error naming the input, parameter or builder call; values Python computes (numpy scalars,
arrays, paths) are taken as a graph file's values; chunked ``process`` calls equal one pass, NaN handling included.
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from flowtex.errors import FlowtexError, GraphError, InputError
from flowtex.graph.builder import GraphBuilder


def smoothing(rate=1000.0, seed=0, order=2, cutoff_hz=50.0, every=1) -> GraphBuilder:
    return (GraphBuilder("g", rate=rate, seed=seed).input("x", unit="N")
            .node("f", "butterworth", every=every, order=order, cutoff_hz=cutoff_hz)
            .edge("x -> f.x").output("y", "f.y"))


@pytest.fixture(scope="module")
def graph():
    return smoothing().build()


@pytest.mark.parametrize(("value", "words"), [
    (np.ones(3) + 1j, "complex"), (["a"], "text"), (np.array(["2020-01-01"], dtype="datetime64[D]"), "timestamps"),
    (1.0, "expected a 1-D array over time, got shape ()"), (np.ones((3, 2)), "expected a 1-D array over time"),
    ([[1.0], [2.0, 3.0]], "not an array of numbers"),
])
def test_run_refuses_what_is_not_a_signal_naming_the_input(graph, value, words) -> None:
    # complex was cast silently (imaginary part lost), a scalar raised IndexError, text a bare ValueError
    with pytest.raises(InputError) as err:
        graph.run({"x": value})
    assert "'x'" in str(err.value) and words in str(err.value) and "\n" not in str(err.value)


@pytest.mark.parametrize(("call", "words"), [
    (lambda g: g.run(np.ones(5)), "pass the inputs as a mapping of input name to array, e.g. {'x': x}"),
    (lambda g: g.run({"x": np.ones(5)}, seed="a"), "seed must be an integer >= 0, got 'a'"),
    (lambda g: g.run({"x": np.ones(5)}, seed=-1), "seed must be an integer >= 0, got -1"),
    (lambda g: g.run_ticks(-1), "n must be an integer >= 0, got -1"),
    (lambda g: g.run_ticks(2.5), "n must be an integer >= 0, got 2.5"),
    (lambda g: g.run_ticks(10**12), "graph 'g': run_ticks n=1,000,000,000,000 would fill 2,000,000,000,000 values, more "
                                    "than a recording may hold (100,000,000); run fewer ticks"),  # numpy's MemoryError
    (lambda g: g.with_block_rows(0), "block_rows must be an integer >= 1, got 0"),
])
def test_wrong_arguments_are_named(graph, call, words) -> None:
    with pytest.raises(InputError) as err:
        call(graph)
    assert words in str(err.value)


def test_numpy_values_and_paths_build_the_graph_their_python_twins_build(hatt_files) -> None:
    # rate=np.float32(1000), every=np.int64(2), order=np.int64(2) were refused ("got np.int64(2)"), a Path as models too
    x = np.random.default_rng(5).standard_normal(400)
    want = smoothing(every=2).build().run({"x": x})["y"]
    got = smoothing(rate=np.float32(1000.0), seed=np.int64(0), order=np.int64(2), cutoff_hz=np.float64(50.0),
                    every=np.int64(2)).build().run({"x": x})["y"]
    np.testing.assert_array_equal(got, want)

    def lookup(models) -> GraphBuilder:
        return (GraphBuilder("t").input("speed", unit="mm/s").input("force", unit="N")
                .node("l", "texture_lookup", models=models).edge("speed -> l.speed").edge("force -> l.force")
                .output("v", "l.variance"))
    inputs = {"speed": np.linspace(0, 300, 40), "force": np.linspace(0, 4, 40)}
    by_path = lookup(Path(hatt_files[0])).build().run(inputs)["v"]
    np.testing.assert_array_equal(by_path, lookup(str(hatt_files[0])).build().run(inputs)["v"])


def test_a_model_object_of_the_wrong_kind_names_what_the_parameter_takes() -> None:
    builder = (GraphBuilder("t").input("speed", unit="mm/s").input("force", unit="N")
               .node("l", "texture_lookup", models={"cork": 1}).edge("speed -> l.speed").edge("force -> l.force")
               .output("v", "l.variance"))
    with pytest.raises(GraphError) as err:
        builder.resolve()
    assert "parameter 'models' expected a non-empty string (a file path) or a loaded TextureModelSet" in str(err.value)


@pytest.mark.parametrize("again", [
    lambda b: b.node("f", "gain", k=3.0), lambda b: b.input("x"), lambda b: b.output("y", "x"),
])
def test_a_name_given_twice_is_refused_not_replaced(again) -> None:
    # a second node("f", ...) silently replaced the first, where a graph file refuses a duplicate key
    with pytest.raises(GraphError) as err:
        again(smoothing())
    assert "duplicate" in str(err.value) and "first defined at GraphBuilder." in str(err.value)
    assert "\n" not in str(err.value)


def _cuts(n: int):
    return st.lists(st.integers(0, n), max_size=6).map(lambda c: [0, *sorted(c), n])


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_process_in_chunks_equals_one_pass_when_holding_nan(graph, data) -> None:
    # "hold" started each chunk from 0, so a chunk beginning with NaN differed from the one-pass run
    n = 150
    x = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1))).standard_normal(n)
    x[data.draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=20))] = np.nan
    one = graph.run({"x": x}, nonfinite="hold")["y"].copy()
    graph.reset()
    cuts = data.draw(_cuts(n))
    parts = [graph.process({"x": x[a:b]}, nonfinite="hold")["y"].copy() for a, b in itertools.pairwise(cuts)]
    np.testing.assert_array_equal(np.concatenate(parts), one)
    graph.reset()
    assert graph.process({"x": np.array([np.nan])}, nonfinite="hold")["y"][0] == 0.0  # reset forgets the held value


@pytest.mark.parametrize(("spoil", "words"), [
    (lambda ms: {"variance": -ms.variance}, "variance is -"),  # rendered silence without a word
    (lambda ms: {"speeds": ms.speeds[:5]}, "has 25 values but there are 5 models"),  # a numpy concatenate message
    (lambda ms: {"triangles": ms.triangles + 100}, "names model"),
])
def test_a_model_set_built_in_memory_gets_the_checks_its_file_would(spoil, words) -> None:
    import dataclasses

    from flowtex.datasets import default_surface
    from flowtex.errors import ParamError
    from flowtex.registry import load_registry

    ms = default_surface()
    bad = dataclasses.replace(ms, **spoil(ms))
    with pytest.raises(ParamError) as err:
        load_registry().types["texture_lookup"].processor(models=bad)
    assert err.value.param == "models" and words in str(err.value) and "\n" not in str(err.value)
    builder = (GraphBuilder("t").input("speed", unit="mm/s").input("force", unit="N")
               .node("l", "texture_lookup", models=bad).edge("speed -> l.speed").edge("force -> l.force")
               .output("v", "l.variance"))
    with pytest.raises(GraphError, match=f"GraphBuilder.node.*models=.*{words[:12]}"):
        builder.resolve()


@pytest.mark.parametrize(("change", "words"), [
    ({"a": [np.array([1.0, -2.5, 1.6])] * 3}, "feature 0: the filter is unstable"),  # IndexError in the node before
    ({"amplitudes": np.array([np.nan, 7.0, 12.0])}, "must be finite"),  # NaN samples out of the node before
    ({"axis": np.zeros(3)}, "axis must be a non-zero finite 3-vector"),  # silence before
    ({"b": [np.array([1.0])] * 2}, "one entry per feature"),
])
def test_a_pattern_built_in_memory_is_checked_when_made(change, words) -> None:
    from flowtex.datasets.patterns import resonance
    from flowtex.models.patterns import Pattern

    b, a = resonance(180.0, 0.006, 1000.0)
    fields = {"sample_rate_hz": 1000.0, "axis": np.array([1.0, 0.0, 0.0]), "origin": np.zeros(3),
              "positions_mm": np.array([2.0, 4.0, 6.0]), "amplitudes": np.array([10.0, 7.0, 12.0]), "b": [b] * 3, "a": [a] * 3}
    Pattern(**fields)  # the unchanged pattern is fine
    with pytest.raises(ValueError, match=words):
        Pattern(**(fields | change))


def test_step_refuses_a_vector_input_it_would_fill_or_truncate() -> None:
    g = (GraphBuilder("v").input("p", shape=3, unit="mm").node("s", "speed_estimator").edge("p -> s.position")
         .output("v", "s.speed").build())
    for value, words in ((1.0, "got shape ()"),  # filled all three components
                         (np.ones(3) + 1j, "complex128 values, not real numbers"),  # dropped the imaginary parts
                         (["a", "b", "c"], "<U1 values, not real numbers"), (np.ones(2), "got shape (2,)")):
        with pytest.raises(FlowtexError) as err:
            g.step({"p": value})
        assert str(err.value).startswith("input 'p' has shape (3,) (3 numbers); step() ") and words in str(err.value)
    g.reset()
    by_list = [g.step({"p": [0.1 * k, 0.0, 0.0]})["v"] for k in range(5)]
    g.reset()
    by_row = [g.step({"p": np.array([[0.1 * k, 0.0, 0.0]])})["v"] for k in range(5)]
    assert by_list == by_row


_DTYPES = st.one_of(hnp.scalar_dtypes(), hnp.unicode_string_dtypes(), hnp.floating_dtypes(endianness=">"))


@settings(max_examples=150, deadline=None)
@given(value=hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=6)),
       policy=st.sampled_from(["error", "hold", "zero", "pass"]))
def test_any_array_runs_or_is_one_flowtex_error(graph, value, policy) -> None:
    try:
        y = graph.run({"x": value}, nonfinite=policy)["y"]
    except FlowtexError as exc:
        assert "\n" not in str(exc)
        return
    assert y.shape == (value.shape[0],) and y.dtype == np.float64
    finite = np.asarray(value, dtype=np.float64)
    if policy != "pass" and np.all(np.abs(finite[np.isfinite(finite)]) <= 1e6):
        assert np.isfinite(y).all()  # NaN/inf were held or zeroed; moderate values stay finite through a stable filter


def test_overrides_from_python_code_are_taken_or_named() -> None:
    x = np.random.default_rng(9).standard_normal(200)
    want = smoothing(order=3, cutoff_hz=80.0).build().run({"x": x})["y"]
    got = smoothing().build(overrides={"f.order": np.int64(3), "f.cutoff_hz": np.float32(80.0)}).run({"x": x})["y"]
    np.testing.assert_array_equal(got, want)  # np.int64(3) was "expected an integer, got np.int64(3)"
    for overrides, words in (({3: 1}, "an override's key is 'NODE.PARAM' or 'rate', got 3"),  # AttributeError before
                             ([("f.order", 3)], "overrides must be a mapping")):
        with pytest.raises(GraphError, match=words):
            smoothing().spec(overrides)


def test_one_plugin_folder_given_as_a_string_is_one_folder(tmp_path) -> None:
    # plugins="folder" was read as one folder per character ("/.../f: plugin folder does not exist")
    folder = tmp_path / "my_plugins"
    folder.mkdir()
    (folder / "twice_gain.py").write_text(
        "import numpy as np\nfrom numba import njit\nfrom flowtex.node_api import Node, NodeState, Param, Port\n\n\n"
        "@njit(cache=True)\ndef k(p, s, si, x, y):\n    for t in range(x.shape[0]):\n        y[t, 0] = 2.0 * x[t, 0]\n\n\n"
        "class TwiceGain(Node):\n    \"\"\"Doubles.\"\"\"\n    type_name = \"twice_gain_api\"\n    inputs = {\"x\": Port((), \"*\")}\n"
        "    outputs = {\"y\": Port((), \"=x\")}\n    kernel = k\n")
    builder = GraphBuilder("p").input("x").node("d", "twice_gain_api").edge("x -> d.x").output("y", "d.y")
    for folders in (str(folder), folder, (folder,)):
        np.testing.assert_array_equal(builder.build(plugins=folders).run({"x": np.arange(4.0)})["y"], 2.0 * np.arange(4.0))


def test_node_states_beyond_the_limit_are_refused_at_the_largest_node(monkeypatch) -> None:
    # The limit is 1 GiB; lowered here so that a delay line of 5000 samples crosses it without allocating a gigabyte.
    monkeypatch.setattr("flowtex.graph.resolve.MAX_STATE_VALUES", 4000)
    builder = (GraphBuilder("s").input("x").node("small", "delay", samples=10).node("big", "delay", samples=5000)
               .edge("x -> small.x").edge("small.y -> big.x").output("y", "big.y"))
    with pytest.raises(GraphError) as err:
        builder.resolve()
    assert str(err.value).startswith("GraphBuilder.node('big', 'delay'): node 'big' (delay): its parameters and state hold ")
    assert "flowtex allocates at most 4,000 (flowtex.limits.MAX_STATE_VALUES)" in str(err.value)
    monkeypatch.setattr("flowtex.graph.resolve.MAX_STATE_VALUES", 10_000)
    builder.resolve()


def test_a_data_frame_or_an_npz_file_is_a_mapping_of_inputs(graph, tmp_path) -> None:
    pd = pytest.importorskip("pandas")
    x = np.random.default_rng(11).standard_normal(50)
    want = graph.run({"x": x})["y"].copy()
    np.testing.assert_array_equal(graph.run(pd.DataFrame({"x": x}))["y"], want)
    np.savez(tmp_path / "r.npz", x=x)
    with np.load(tmp_path / "r.npz") as npz:
        np.testing.assert_array_equal(graph.run(npz)["y"], want)


_GARBAGE = st.one_of(
    st.none(), st.booleans(), st.integers(-10**20, 10**20), st.floats(allow_nan=True, allow_infinity=True),
    st.text(max_size=8), st.lists(st.floats(-1e3, 1e3), max_size=4), st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
    st.sampled_from([np.int64(3), np.float32(0.5), np.bool_(True), np.array([1.0, 2.0]), np.zeros((2, 2)), Path("nowhere.json")]),
)


def _plain_types() -> list[str]:
    from flowtex.registry import load_registry

    types = load_registry().types
    return sorted(t for t in types if not any(p.kind == "path" for p in types[t].params.values()))


@settings(max_examples=300, deadline=None)  # 4000 examples found nothing more on 2026-11-27
@given(data=st.data())
def test_any_parameter_values_build_or_are_graph_errors(data) -> None:
    # Every built-in node type (those without a file parameter), each parameter either left out, given a valid-looking
    # value or garbage of any Python/numpy kind: the builder resolves or raises GraphError, one line per problem.
    from flowtex.registry import load_registry

    type_name = data.draw(st.sampled_from(_plain_types()))
    cls = load_registry().types[type_name]
    params = {}
    for name, decl in cls.params.items():
        choice = data.draw(st.sampled_from(["omit", "default", "garbage"]))
        if choice == "garbage" or (choice == "default" and decl.required):
            params[name] = data.draw(_GARBAGE)
        elif choice == "default":
            params[name] = decl.default
    builder = GraphBuilder("fuzz")
    for port_name, port in cls.inputs.items():
        shape = port.shape if isinstance(port.shape, tuple) else (3,) if port.shape is None else ()
        builder.input(f"in_{port_name}", shape=shape, unit="" if port.unit in ("*", "") or port.unit.startswith("=") else port.unit)
        builder.edge(f"in_{port_name} -> n.{port_name}")
    builder.node("n", type_name, **params)
    for port_name in cls.outputs:
        builder.output(f"out_{port_name}", f"n.{port_name}")
    try:
        builder.resolve()
    except GraphError as exc:
        assert all("\n" not in str(d) for d in exc.diagnostics)
