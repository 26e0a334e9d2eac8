"""Node.processor() given what Python code gets wrong: each mistake is one flowtex error naming the input or parameter.

A processor runs a node's numba kernel on the caller's arrays, and kernels index their ports' columns unchecked: an
array narrower than the port's declared shape was read past its end (garbage, or a crash), so the width is checked
before the node is built. Chunked calls must equal one call bit for bit, NaN handling included.
"""

from __future__ import annotations

import inspect
import itertools
from pathlib import Path

import numpy as np
import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from numba import njit

from flowtex.errors import DataError, FlowtexError, InputError, ParamError
from flowtex.node_api import Field, Layout, Memory, Node, Port
from flowtex.registry import load_registry


def node_type(name: str):
    return load_registry().types[name]


@pytest.mark.parametrize(("type_name", "params", "inputs", "port", "want"), [
    ("cross", {}, {"a": np.ones(4), "b": np.ones((4, 3))}, "a", 3),
    ("cross", {}, {"a": np.ones((4, 3)), "b": np.ones((4, 2))}, "b", 3),
    ("dft321", {}, {"x": np.ones((4, 5))}, "x", 3),
    ("speed_estimator", {}, {"position": np.ones(4)}, "position", 3),
    ("contact", {}, {"position": np.ones((4, 3)), "normal_force": np.ones(4), "normal": np.ones(4)}, "normal", 3),
    ("add", {}, {"a": np.ones((4, 3)), "b": np.ones(4)}, "b", 3),  # b's shape is declared "=a"
    ("surface_switch", {"b_index": 1}, {"index": np.ones(4), "a": np.ones((4, 2)), "b": np.ones((4, 3))}, "b", 2),
    ("first_order_lowpass", {"cutoff_hz": 10.0}, {"x": np.ones((4, 70_000))}, "x", None),  # over the per-tick limit
])
def test_an_array_of_the_wrong_width_is_refused_before_the_kernel_reads_it(type_name, params, inputs, port, want) -> None:
    proc = node_type(type_name).processor(**params)
    with pytest.raises(InputError) as err:
        proc(**inputs)
    message = str(err.value)
    assert f"input {port!r}" in message and "\n" not in message
    assert (f"pass shape (ticks, {want})" in message) if want else "65,536" in message


def test_a_first_call_that_fails_leaves_the_processor_unbuilt() -> None:
    # select's build refuses an index beyond the vector: the processor must not keep half a build (it kept the input
    # specs and then failed on the next call with AttributeError).
    proc = node_type("select").processor(index=4)
    with pytest.raises(ParamError, match="index 4 is out of range"):
        proc(x=np.ones((3, 3)))
    x = np.arange(30.0).reshape(6, 5)
    np.testing.assert_array_equal(proc(x=x)["y"][:, 0], x[:, 4])


@pytest.mark.parametrize(("value", "words"), [
    (np.ones(3) + 1j, "complex"),
    (["a", "b"], "text"),
    (np.array(["2020-01-01"], dtype="datetime64[D]"), "timestamps"),
    (np.array([object()]), "Python objects"),
    ([[1.0], [2.0, 3.0]], "not an array of numbers"),
    (1.0, "one row per tick"),
    (np.ones((2, 2, 2)), "one row per tick"),
])
def test_values_that_are_not_a_signal_are_refused_naming_the_input(value, words) -> None:
    # complex and timestamps used to be converted silently (imaginary part dropped; nanoseconds as values)
    with pytest.raises(InputError) as err:
        node_type("gain").processor(k=2.0)(x=value)
    assert "'x'" in str(err.value) and words in str(err.value) and "\n" not in str(err.value)


def test_arrays_of_any_layout_and_byte_order_give_the_same_output() -> None:
    x = np.random.default_rng(1).standard_normal(64)
    want = node_type("butterworth").processor(order=2, cutoff_hz=50.0)(x=x)["y"]
    readonly = x.copy()
    readonly.flags.writeable = False
    strided = np.repeat(x, 2)[::2]
    for variant in (x.astype(">f8"), readonly, strided, list(x)):
        got = node_type("butterworth").processor(order=2, cutoff_hz=50.0)(x=variant)["y"]
        np.testing.assert_array_equal(got, want)
    assert node_type("butterworth").processor(order=2, cutoff_hz=50.0)(x=np.ones(0))["y"].shape == (0, 1)


def test_numpy_scalars_arrays_and_paths_are_parameters_as_python_values(hatt_files) -> None:
    # What Python code computes (np.int64 from a size, float32 from a recording, an array of band edges, a Path)
    # was refused as "expected an integer, got np.int64(4)".
    x = np.random.default_rng(2).standard_normal(300)
    want = node_type("butterworth").processor(order=4, cutoff_hz=[10.0, 200.0], kind="bandpass")(x=x)["y"]
    got = node_type("butterworth").processor(rate=np.float32(1000.0), seed=np.int64(0), order=np.int64(4),
                                             cutoff_hz=np.array([10.0, 200.0]), kind=np.str_("bandpass"))(x=x)["y"]
    np.testing.assert_array_equal(got, want)
    speed, force = np.linspace(0, 200, 50), np.linspace(0, 3, 50)
    by_str = node_type("texture_lookup").processor(models=str(hatt_files[0]))(speed=speed, force=force)
    by_path = node_type("texture_lookup").processor(models=hatt_files[0])(speed=speed, force=force)
    for name in by_str:
        np.testing.assert_array_equal(by_path[name], by_str[name])


@pytest.mark.parametrize(("settings_", "words"), [
    ({"rate": 0}, "rate must be"), ({"rate": float("nan")}, "rate must be"), ({"rate": -1000.0}, "rate must be"),
    ({"rate": "fast"}, "rate must be"), ({"rate": True}, "rate must be"), ({"seed": -1}, "seed must be"),
    ({"seed": 1.5}, "seed must be"), ({"seed": "a"}, "seed must be"), ({"name": 5}, "name must be"),
    ({"nonfinite": "skip"}, "nonfinite must be"),
])
def test_rate_seed_name_and_policy_are_checked_and_named(settings_, words) -> None:
    # a rate of 0 or -1000 was passed on, and the filter design complained about "the Nyquist frequency -500 Hz"
    with pytest.raises(ParamError) as err:
        node_type("butterworth").processor(order=2, cutoff_hz=50.0, **settings_)
    assert words in str(err.value) and err.value.param == next(iter(settings_))


GRAPH_WITH = """flowtex: 1
rate: {rate}
seed: {seed}
inputs: {{x: {{}}}}
nodes:
  f: {{type: gain, params: {{k: 2.0}}, every: {every}}}
edges: [x -> f.x]
outputs: {{y: f.y}}
"""


@pytest.mark.parametrize(("setting", "value"), [
    *[("rate", v) for v in (0, -5, 1e7, "fast", True, 500, 4.0e3, 1e6)],
    *[("seed", v) for v in (-1, 2.5, 4.0, "a", 7, 10**20, False)],
    *[("every", v) for v in (0, 2.5, 3.0, 2_000_000, True, 2, "2")],
])
def test_a_processor_setting_is_read_by_the_graph_files_declaration(setting, value) -> None:
    """One rule for a graph's rate, seed and a node's every: a processor refuses exactly what a graph file refuses, with
    the graph file's message (flowtex.schema.graph), and reads what it accepts the same way (4.0 is the integer 4)."""
    from flowtex.errors import GraphError
    from flowtex.graph.spec import parse_spec

    given = {"rate": 1000, "seed": 0, "every": 1, setting: value}
    text = GRAPH_WITH.format(**{k: yaml.safe_dump(v, default_flow_style=True).strip().removesuffix("...").strip()
                                for k, v in given.items()})
    try:
        spec = parse_spec(text, Path("g.yaml"))
        graph_message = None
    except GraphError as e:
        graph_message = str(e).split(": ", 1)[1]  # after g.yaml:line:col
    try:
        proc = node_type("gain").processor(k=2.0, name="f", **given)
    except ParamError as e:
        assert graph_message is not None, f"the graph file takes {setting}: {value!r}, the processor refused: {e}"
        assert str(e).endswith(": " + graph_message) and e.param == setting
        return
    assert graph_message is None, f"the graph file refuses {setting}: {value!r} ({graph_message}), the processor took it"
    read = {"rate": spec.rate, "seed": spec.seed, "every": spec.nodes["f"].every}[setting]
    got = {"rate": proc.context.rate, "seed": proc.seed, "every": proc.every}[setting]
    assert got == read and type(got) is type(read)


def test_inputs_are_passed_by_port_name() -> None:
    with pytest.raises(InputError, match="pass each input by its port name, e.g. x=array"):
        node_type("gain").processor(k=1.0)(np.ones(3))


def _split_points(n: int):
    return st.lists(st.integers(0, n), max_size=6).map(lambda cuts: [0, *sorted(cuts), n])


@settings(max_examples=40, deadline=None)
@given(data=st.data())
def test_nan_is_refused_by_default_and_held_across_calls_when_asked(data) -> None:
    n = 120
    x = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1))).standard_normal(n)
    x[data.draw(st.lists(st.integers(0, n - 1), min_size=1, max_size=10))] = data.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
    with pytest.raises(DataError, match="input 'x' has .* non-finite"):
        node_type("first_order_lowpass").processor(cutoff_hz=20.0)(x=x)
    cuts = data.draw(_split_points(n))
    for policy in ("hold", "zero"):
        one = node_type("first_order_lowpass").processor(cutoff_hz=20.0, nonfinite=policy)(x=x)["y"]
        proc = node_type("first_order_lowpass").processor(cutoff_hz=20.0, nonfinite=policy)
        chunked = np.vstack([proc(x=x[a:b])["y"] for a, b in itertools.pairwise(cuts)])
        np.testing.assert_array_equal(chunked, one)
        assert np.isfinite(one).all()


@pytest.mark.parametrize(("type_name", "params", "inputs"), [
    ("butterworth", {"order": 3, "cutoff_hz": [20.0, 90.0], "kind": "bandpass"}, {"x": (3,)}),
    ("speed_estimator", {}, {"position": (3,)}),
    ("dft321", {}, {"x": (3,)}),
    ("differentiator", {}, {"x": ()}),
    ("delay", {"samples": 7}, {"x": (2,)}),
    ("compliance_estimator", {}, {"normal_force": (), "acceleration": (3,)}),
    ("white_noise", {}, {"variance": ()}),  # random state: its generator carries over too
])
@settings(max_examples=15, deadline=None)
@given(data=st.data())
def test_chunked_calls_equal_one_call_bit_for_bit(type_name, params, inputs, data) -> None:
    n = 200
    rng = np.random.default_rng(data.draw(st.integers(0, 2**32 - 1)))
    arrays = {k: np.abs(rng.standard_normal((n, *shape))) for k, shape in inputs.items()}  # >= 0: variances too
    one = node_type(type_name).processor(**params)(**arrays)
    proc = node_type(type_name).processor(**params)
    cuts = data.draw(_split_points(n))
    parts = [proc(**{k: a[lo:hi] for k, a in arrays.items()}) for lo, hi in itertools.pairwise(cuts)]
    for name, want in one.items():
        np.testing.assert_array_equal(np.vstack([p[name] for p in parts]), want)


_RAISING = Memory(state=Layout("float", [Field("acc", 1, "running sum")]))
_ACC = _RAISING.state.const("acc")


@njit(cache=True)
def _raising_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        s[_ACC] += x[t, 0]
        if s[_ACC] > 1e6:
            raise ValueError("accumulator overflow")
        y[t, 0] = s[_ACC]


class _Raising(Node):
    """A running sum whose kernel raises beyond 1e6 (a plugin's kernel that raises part-way through a call)."""

    type_name = "raising_test"
    inputs = {"x": Port((), "*")}
    outputs = {"y": Port((), "=x")}
    kernel = _raising_kernel
    memory = _RAISING


def test_a_kernel_that_raises_leaves_the_state_as_before_the_call() -> None:
    proc = _Raising.processor()
    proc(x=np.array([1.0, 2.0]))
    with pytest.raises(FlowtexError, match="its kernel raised ValueError: accumulator overflow; the processor's state is as before"):
        proc(x=np.array([5.0, 1e7, 3.0]))
    np.testing.assert_array_equal(proc(x=np.array([4.0]))["y"][:, 0], [7.0])



class _ForgetsY(_Raising):
    """A resolve() that returns no spec for the declared output y."""

    type_name = "forgets_y_test"

    def resolve(self, inputs):
        return {}


def test_a_resolve_missing_an_output_is_named_not_a_key_error() -> None:
    with pytest.raises(FlowtexError) as err:
        _ForgetsY.processor()(x=np.ones(3))
    line = inspect.getsourcelines(_ForgetsY.resolve)[1]
    assert str(err.value).startswith(f"tests/nodes/test_processor_hostile.py:{line}: node 'forgets_y_test': resolve() of "
                                     "graph node 'forgets_y_test' returned no spec for output(s) 'y'")


@njit
def _untyped_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0] + "a"


class _Untyped(_Raising):
    """A kernel that does not compile for its ports."""

    type_name = "untyped_test"
    kernel = _untyped_kernel


def test_a_kernel_that_does_not_compile_is_named_at_its_line_not_a_typing_error() -> None:
    # "its kernel raised TypingError: Failed in nopython mode pipeline (step: nopython frontend)" said nothing useful
    with pytest.raises(FlowtexError) as err:
        _Untyped.processor()(x=np.ones(3))
    line = inspect.getsourcelines(_untyped_kernel)[1] + 3  # the addition of a string
    assert str(err.value).startswith(f"tests/nodes/test_processor_hostile.py:{line}: node 'untyped_test': kernel "
                                     "_untyped_kernel does not compile for its ports")


_DTYPES = st.one_of(hnp.scalar_dtypes(), hnp.byte_string_dtypes(), hnp.unicode_string_dtypes(),
                    hnp.floating_dtypes(endianness="<"), hnp.floating_dtypes(endianness=">"))


@settings(max_examples=150, deadline=None)
@given(type_name=st.sampled_from(["gain", "cross", "speed_estimator", "first_order_lowpass"]),
       arrays=st.lists(hnp.arrays(_DTYPES, hnp.array_shapes(min_dims=0, max_dims=3, min_side=0, max_side=5)),
                       min_size=2, max_size=2))
def test_any_array_gives_outputs_of_its_length_or_one_flowtex_error(type_name, arrays) -> None:
    # Whatever dtype, shape, byte order or values Python code hands in: either the node runs (every output has one
    # row per tick) or a one-line flowtex error is raised -- never a numpy, numba or Python error, never a crash.
    cls = node_type(type_name)
    params = {"gain": {"k": 2.0}, "first_order_lowpass": {"cutoff_hz": 10.0}}.get(type_name, {})
    inputs = dict(zip([n for n, p in cls.inputs.items() if not p.optional], arrays, strict=False))
    try:
        out = cls.processor(**params)(**inputs)
    except FlowtexError as exc:
        assert "\n" not in str(exc)
        return
    n = {np.asarray(a).shape[0] for a in inputs.values()}.pop()
    for name, y in out.items():
        assert y.dtype == np.float64 and y.ndim == 2 and y.shape[0] == n, name
