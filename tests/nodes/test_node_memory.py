"""Every built-in node declares its memory once (issue 24 item 1): build() packs exactly the declared arrays, and the
kernel reads and writes nothing past them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from flowtex.datasets.model_sets import cork_like_model_set
from flowtex.datasets.taps import synthetic_tap_library
from flowtex.errors import FlowtexError
from flowtex.io.patternfile import Pattern, write_pattern
from flowtex.io.taplib import write_tap_library
from flowtex.kernelprobe import parameter_values, shape_cases
from flowtex.node_api import BuildContext, Node, PortSpec
from flowtex.node_params import load_files
from flowtex.registry import BUILTIN_TYPES, load_registry

RATE_HZ = 1000.0
TICKS = 40
GUARD = 16
"""Values placed after each of p, s and si: a kernel that reads past its declared memory sees them, one that writes
past it changes them."""
FLOAT_GUARDS = (np.nan, -3.5e300)
INT_GUARDS = (-(2**62), 2**61 + 12345)


def _pattern(tmp_path: Path) -> Path:
    pattern = Pattern(RATE_HZ, np.array([1.0, 0.0, 0.0]), np.zeros(3), np.array([-0.5, 0.0, 0.5]), np.array([1.0, 0.5, 2.0]),
                      [np.array([1.0, 0.5]), np.array([1.0]), np.array([0.5, 0.2, 0.1])],
                      [np.array([1.0, -0.5]), np.array([1.0]), np.array([1.0, -0.3, 0.02])])
    return write_pattern(tmp_path / "p.json", pattern)


GIVEN = {  # type -> its parameters (made when that type is built: a model set costs 30 ms, made for every type before)
    "texture_lookup": lambda tmp_path: {"models": cork_like_model_set()},
    "patterned_texture": lambda tmp_path: {"pattern": str(_pattern(tmp_path))},
    "tap_player": lambda tmp_path: {"library": str(write_tap_library(tmp_path / "taps.json",
                                                                     synthetic_tap_library(sample_rate_hz=RATE_HZ)))},
    "coulomb_friction": lambda tmp_path: {"mu": 0.5},
    "dahl_friction": lambda tmp_path: {"mu": 0.5},
    "butterworth": lambda tmp_path: {"order": 3, "cutoff_hz": [50.0]},
    "resample": lambda tmp_path: {"to_hz": 500.0},
    "select": lambda tmp_path: {"index": 0},
}


def _params(cls: type[Node], tmp_path: Path) -> dict[str, Any]:
    """Valid parameters: kernelprobe's made-up values, with a real model set or file where a type needs one."""
    given = GIVEN[cls.type_name](tmp_path) if cls.type_name in GIVEN else {}
    values = {}
    for name, param in cls.params.items():
        if name in given:
            values[name] = param.coerce(given[name], tmp_path)
        elif param.required:
            values[name] = parameter_values(cls)[name]
        else:
            values[name] = None if param.default is None else param.coerce(param.default, tmp_path)
    return values


def _builds(cls: type[Node], tmp_path: Path) -> list[tuple[Node, Any, dict[str, PortSpec], dict[str, PortSpec]]]:
    """The node built at each of kernelprobe's shape cases that it accepts (at least one)."""
    built = []
    for shapes in shape_cases(cls):
        in_specs = {name: PortSpec(shapes[name], "" if port.unit in ("*",) or port.unit.startswith("=") else port.unit)
                    for name, port in cls.inputs.items()}
        values, files = load_files(cls, _params(cls, tmp_path))  # files read into objects, as the resolver does
        node = cls("n", values, BuildContext(rate=RATE_HZ, base_dir=tmp_path, files=files))
        try:
            out_specs = node.resolve(in_specs)
        except FlowtexError:  # e.g. select or arma_synth on a scalar: the other case builds
            continue
        state = node.build(in_specs, out_specs)
        if cls.uses_seed:
            node.seed_state(state.state, state.istate, np.random.SeedSequence(7))
        built.append((node, state, in_specs, out_specs))
    assert built, f"{cls.type_name}: no shape case builds"
    return built


@pytest.mark.parametrize("type_name", sorted(BUILTIN_TYPES))
def test_build_packs_the_declared_memory(type_name: str, tmp_path: Path) -> None:
    cls = load_registry().types[type_name]
    assert cls.memory is not None, f"{type_name} declares no memory (class attribute memory = Memory(...))"
    for node, state, _, _ in _builds(cls, tmp_path):
        sizes = getattr(node, "memory_sizes", {})
        declared = cls.memory.sizes(sizes)
        packed = (np.asarray(state.params).size, np.asarray(state.state).size, np.asarray(state.istate).size)
        assert packed == declared, f"{type_name} built with sizes {sizes}: packed (p, s, si) {packed}, declared {declared}"


def _run_guarded(cls: type[Node], state: Any, inputs: list[np.ndarray], widths: list[int], guard: int
                 ) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Outputs of the kernel on views of p, s, si followed by guard values, and the guard values afterwards."""
    arrays = []
    for values, dtype, guards in ((state.params, np.float64, FLOAT_GUARDS), (state.state, np.float64, FLOAT_GUARDS),
                                  (state.istate, np.int64, INT_GUARDS)):
        values = np.asarray(values, dtype=dtype).ravel()
        arrays.append((np.concatenate([values, np.full(GUARD, guards[guard], dtype=dtype)]), values.size))
    outs = [np.zeros((TICKS, w)) for w in widths]
    cls.get_kernel()(*(buf[:n] for buf, n in arrays), *inputs, *outs)
    return outs, [buf[n:] for buf, n in arrays]


@pytest.mark.parametrize("type_name", sorted(BUILTIN_TYPES))
def test_kernel_stays_inside_the_declared_memory(type_name: str, tmp_path: Path) -> None:
    cls = load_registry().types[type_name]
    rng = np.random.default_rng(5)
    for _node, state, in_specs, out_specs in _builds(cls, tmp_path):
        inputs = [np.ascontiguousarray(rng.uniform(-1.0, 1.0, (TICKS, spec.width))) for spec in in_specs.values()]
        widths = [out_specs[name].width for name in cls.outputs]
        runs = []
        for guard in (0, 1):
            copy = type(state)(np.array(state.params, copy=True), np.array(state.state, copy=True),
                               np.array(state.istate, copy=True))
            outs, after = _run_guarded(cls, copy, inputs, widths, guard)
            for values, want in zip(after, (FLOAT_GUARDS[guard], FLOAT_GUARDS[guard], INT_GUARDS[guard]), strict=True):
                assert np.array_equal(values, np.full(GUARD, want, dtype=values.dtype), equal_nan=True), \
                    f"{type_name}: the kernel wrote past its declared p, s or si"
            runs.append(outs)
        for a, b in zip(*runs, strict=True):
            assert np.array_equal(a, b, equal_nan=True), f"{type_name}: the output depends on values past its declared memory"
