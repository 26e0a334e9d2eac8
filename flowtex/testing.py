"""Golden tests for graphs: pin a graph's outputs on an input file.

In a test (the pytest plugin is registered automatically when flowtex is installed)::

    def test_texture_graph(golden):
        golden.check("graphs/hatt_texture.yaml", "graphs/data/exploration.npz",
                     "tests/golden/hatt_texture.npz")

The first run fails and tells you to create the golden file with
``pytest --update-golden``; review the file once (plot it, look at the
numbers), commit it, and from then on any change of behaviour fails the test.

Comparison is exact by default: a graph's outputs depend only on its inputs
and seed, so the same code on the same machine gives the same bits. Pass
``rtol``/``atol`` when a graph must also pass on machines whose floating point
differs (for example CPUs without fused multiply-add, which changes the
last bits of filter outputs): ``rtol=1e-9`` is a sensible start for filter
chains; noise-driven outputs depend on every bit of the excitation path, so
keep them exact or compare statistics instead.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

UPDATE_OPTION = "--update-golden"


class GoldenMismatch(AssertionError):
    """The graph's outputs differ from the golden file."""


def run_graph_on_file(graph_path: str | Path, input_path: str | Path, seed: int | None = None,
                      overrides: Mapping[str, Any] | None = None, plugins: tuple[str | Path, ...] = ()) -> dict[str, np.ndarray]:
    """Load ``graph_path`` and run it on the recording ``input_path``."""
    from .graph.compiled import load_graph
    from .runtime.offline import run_recording

    graph = load_graph(graph_path, overrides, plugins)
    return run_recording(graph, input_path, None, seed=seed, progress=False)


def compare_outputs(actual: Mapping[str, np.ndarray], expected: Mapping[str, np.ndarray],
                    rtol: float = 0.0, atol: float = 0.0) -> list[str]:
    """Problems found comparing two output sets (empty if they match)."""
    problems = []
    for name in sorted(set(actual) | set(expected)):
        if name not in expected:
            problems.append(f"output {name!r} is new (not in the golden file)")
            continue
        if name not in actual:
            problems.append(f"output {name!r} is missing (the golden file has it)")
            continue
        a, e = np.asarray(actual[name]), np.asarray(expected[name])
        if a.shape != e.shape:
            problems.append(f"output {name!r}: shape {a.shape} != golden {e.shape}")
            continue
        if rtol == 0.0 and atol == 0.0:
            bad = ~((a == e) | (np.isnan(a) & np.isnan(e)))
        else:
            bad = ~np.isclose(a, e, rtol=rtol, atol=atol, equal_nan=True)
        if bad.any():
            idx = np.argwhere(bad)[0]
            first = tuple(int(i) for i in idx)
            err = np.abs(a - e)[bad]
            problems.append(f"output {name!r}: {int(bad.sum())} of {a.size} values differ; first at {first}: "
                            f"{a[first]!r} != golden {e[first]!r}; max |diff| {np.nanmax(err):.3g}")
    return problems


def check_golden(graph_path: str | Path, input_path: str | Path, golden_path: str | Path, *, update: bool = False,
                 seed: int | None = None, rtol: float = 0.0, atol: float = 0.0,
                 overrides: Mapping[str, Any] | None = None, plugins: tuple[str | Path, ...] = ()) -> dict[str, np.ndarray]:
    """Run the graph on the input and compare with (or, if ``update``, rewrite) the golden file."""
    outputs = run_graph_on_file(graph_path, input_path, seed, overrides, plugins)
    golden_path = Path(golden_path)
    if update:
        golden_path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(golden_path, **outputs)
        return outputs
    if not golden_path.exists():
        raise GoldenMismatch(f"{golden_path}: no golden file yet; run pytest {UPDATE_OPTION} to create it, review it, commit it")
    with np.load(golden_path, allow_pickle=False) as data:
        expected = {k: data[k] for k in data.files}
    problems = compare_outputs(outputs, expected, rtol, atol)
    if problems:
        raise GoldenMismatch(f"{graph_path} on {input_path} differs from {golden_path}:\n  " + "\n  ".join(problems)
                             + f"\nIf the change is intended, run pytest {UPDATE_OPTION} and review the new file.")
    return outputs


class Golden:
    """The ``golden`` fixture: ``golden.check(graph, input, golden_file, **options)``."""

    def __init__(self, update: bool):
        self.update = update

    def check(self, graph_path: str | Path, input_path: str | Path, golden_path: str | Path, **options: Any) -> dict[str, np.ndarray]:
        return check_golden(graph_path, input_path, golden_path, update=self.update, **options)


# --- pytest plugin (entry point 'pytest11') --------------------------------
def pytest_addoption(parser: Any) -> None:
    parser.addoption(UPDATE_OPTION, action="store_true", default=False,
                     help="flowtex: rewrite golden files from the current outputs instead of comparing")


def _golden_fixture(request: Any) -> Golden:
    return Golden(bool(request.config.getoption(UPDATE_OPTION)))


try:  # the fixture exists only when pytest is importable
    import pytest

    golden = pytest.fixture(_golden_fixture, name="golden")
except ImportError:  # pragma: no cover
    pass
