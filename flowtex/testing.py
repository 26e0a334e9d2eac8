"""Golden tests for graphs: pin a graph's outputs on an input file.

In a test (the pytest plugin is registered automatically when flowtex is installed)::

    def test_texture_graph(golden):
        golden.check("graphs/hatt_texture.yaml", "graphs/data/exploration.npz",
                     "tests/golden/hatt_texture.npz")

The first run fails and tells you to create the golden file with
``pytest --update-golden``; review the file once (plot it, look at the
numbers), commit it, and from then on any change of behaviour fails the test.

What is compared: a graph's outputs depend only on its inputs, parameters
and seed, so on one machine the same code gives the same bits. Across
machines it does not: numba compiles for the CPU it runs on (vector width,
fused multiply-add contraction) and numpy/scipy pick CPU-specific kernels, so
the last bits of a filter's output differ, and recursive filters with poles
near the unit circle (texture ARMA models) amplify those differences. The
default comparison therefore allows, per output,

    |actual - golden| <= DEFAULT_RMS_RTOL * RMS(golden output)      (1e-7)

and requires NaN and inf at the same places. Measured with
``benchmarks/golden_spread.py`` (native code vs ``NUMBA_CPU_NAME=generic``, no
fused multiply-add, and vs golden files made on another CPU), the example
graphs move by at most 1.6e-10 x RMS (texture synthesis; filter chains
2e-13): 1e-7 leaves a margin of 600. A rounding error injected into a
recursion with pole radius r grows by its noise gain ~ 1/sqrt(2 (1 - r));
for a pole within ~1e-12 of the unit circle (the closest dsp/arma.K_MAX lets through) that is
1e-16 x 7e5 ~ 1e-10 of the output's RMS, the same order as measured. Real
changes are far larger: on the examples, a parameter changed by 0.1 % moves
outputs by 2e-3 to 1e-2 x RMS, a one-sample shift by at least 0.12 x RMS,
another seed by ~6 x RMS (tests/test_golden_portability.py).

Integer and boolean arrays are compared exactly. Graph outputs are float64
(flags such as ``in_contact`` are 0.0/1.0): a flipped flag differs by 1, far
above the tolerance, so it is caught as well.

Options of ``check``/``check_golden``/``compare_outputs``: ``exact=True``
demands identical bits (same-machine regression checks, e.g. chunked vs one
pass); ``rms_rtol`` sets the RMS-relative tolerance (0 turns it off);
``rtol``/``atol`` add numpy-style per-value terms,
``|diff| <= atol + rtol * |golden| + rms_rtol * RMS``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

UPDATE_OPTION = "--update-golden"


DEFAULT_RMS_RTOL = 1e-7
"""Default tolerance of golden comparisons, relative to each output's RMS (see the module docstring)."""


class GoldenMismatch(AssertionError):
    """The graph's outputs differ from the golden file."""


def run_graph_on_file(graph_path: str | Path, input_path: str | Path, seed: int | None = None,
                      overrides: Mapping[str, Any] | None = None, plugins: tuple[str | Path, ...] = ()) -> dict[str, np.ndarray]:
    """Load ``graph_path`` and run it on the recording ``input_path``."""
    from .graph.compiled import load_graph
    from .runtime.offline import run_recording

    graph = load_graph(graph_path, overrides, plugins)
    return run_recording(graph, input_path, None, seed=seed, progress=False)


def rms(values: np.ndarray) -> float:
    """Root mean square of the finite values of an output (0.0 if there are none)."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.sqrt(np.mean(v * v))) if v.size else 0.0


def _exact_only(a: np.ndarray, e: np.ndarray) -> bool:
    return a.dtype.kind in "biu" or e.dtype.kind in "biu"


def compare_outputs(actual: Mapping[str, np.ndarray], expected: Mapping[str, np.ndarray], rtol: float = 0.0, atol: float = 0.0,
                    *, rms_rtol: float = DEFAULT_RMS_RTOL, exact: bool = False) -> list[str]:
    """Problems found comparing two output sets (empty if they match).

    A value passes if it has the same bits as the expected one (so NaN matches
    NaN and inf the same inf), or if both are finite and
    ``|actual - expected| <= atol + rtol * |expected| + rms_rtol * RMS(expected output)``,
    where RMS is over all finite values of that output in the expected set.
    Integer and boolean arrays, and everything when ``exact`` is true, must be identical. A tolerance must be a finite
    number >= 0 (a negative one made every comparison stricter than exact, silently): ValueError naming it otherwise.
    """
    for label, tol in (("rtol", rtol), ("atol", atol), ("rms_rtol", rms_rtol)):
        if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)) or not 0.0 <= tol < math.inf:
            raise ValueError(f"compare_outputs: {label} must be a finite number >= 0, got {tol!r}")
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
        same = a == e
        if a.dtype.kind in "fc" and e.dtype.kind in "fc":
            same |= np.isnan(a) & np.isnan(e)
        strict = exact or _exact_only(a, e)
        scale = 0.0 if strict else rms(e)
        if strict:
            bad = ~same
            allowed = "must be identical"
        else:
            with np.errstate(invalid="ignore", over="ignore"):
                diff = np.abs(a.astype(np.float64) - e.astype(np.float64))
                bound = atol + rtol * np.abs(e) + rms_rtol * scale
                bad = ~(same | (diff <= bound))
            allowed = _tolerance_text(rtol, atol, rms_rtol, scale)
        if bad.any():
            first = tuple(int(i) for i in np.argwhere(bad)[0])
            with np.errstate(invalid="ignore", over="ignore"):
                err = np.abs(a.astype(np.float64) - e.astype(np.float64))[bad]
            worst = float(np.nanmax(err)) if np.isfinite(err).any() else float("nan")
            rel = f" ({worst / scale:.3g} x RMS)" if scale > 0 and np.isfinite(worst) else ""
            problems.append(f"output {name!r}: {int(bad.sum())} of {a.size} values differ ({allowed}); "
                            f"first at {first}: {a[first].item()!r} != golden {e[first].item()!r}; max |diff| {worst:.3g}{rel}")
    return problems


def _tolerance_text(rtol: float, atol: float, rms_rtol: float, scale: float) -> str:
    terms = [f"{rms_rtol:g} x RMS {scale:.3g}"] if rms_rtol else []
    terms += [f"{rtol:g} x |golden|"] if rtol else []
    terms += [f"{atol:g}"] if atol else []
    return "allowed |diff| " + (" + ".join(terms) if terms else "0")


def check_golden(graph_path: str | Path, input_path: str | Path, golden_path: str | Path, *, update: bool = False,
                 seed: int | None = None, rtol: float = 0.0, atol: float = 0.0, rms_rtol: float = DEFAULT_RMS_RTOL,
                 exact: bool = False, overrides: Mapping[str, Any] | None = None,
                 plugins: tuple[str | Path, ...] = ()) -> dict[str, np.ndarray]:
    """Run the graph on the input and compare with (or, if ``update``, rewrite) the golden file.

    Tolerances as in :func:`compare_outputs`. Raises :class:`GoldenMismatch`,
    whose message (not a traceback) is what pytest shows.
    """
    __tracebackhide__ = True
    outputs = run_graph_on_file(graph_path, input_path, seed, overrides, plugins)
    golden_path = Path(golden_path)
    if update:
        from .io.atomic import atomic_output

        golden_path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_output(golden_path) as tmp:  # an interrupted --update-golden keeps the reviewed file
            np.savez_compressed(tmp, **outputs)
        return outputs
    if not golden_path.exists():
        raise GoldenMismatch(f"{golden_path}: no golden file yet; run pytest {UPDATE_OPTION} to create it, review it, commit it")
    with np.load(golden_path, allow_pickle=False) as data:
        expected = {k: data[k] for k in data.files}
    problems = compare_outputs(outputs, expected, rtol, atol, rms_rtol=rms_rtol, exact=exact)
    if problems:
        raise GoldenMismatch(f"{graph_path} on {input_path} differs from {golden_path}:\n  " + "\n  ".join(problems)
                             + f"\nIf the change is intended, run pytest {UPDATE_OPTION} and review the new file.")
    return outputs


class Golden:
    """The ``golden`` fixture: ``golden.check(graph, input, golden_file, **options)``."""

    def __init__(self, update: bool):
        self.update = update

    def check(self, graph_path: str | Path, input_path: str | Path, golden_path: str | Path, **options: Any) -> dict[str, np.ndarray]:
        __tracebackhide__ = True
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
