"""flowtex.testing's default golden comparison: it passes what another CPU computes, and fails on real changes.

Both directions on the real example graphs and their committed golden files
(tests/golden/, made on another CPU than most machines running this test):

* another CPU, for real: the graph is run in a subprocess with numba's code
  for a generic x86-64 (``NUMBA_CPU_NAME=generic``: SSE2, no fused
  multiply-add), which gives different bits than this machine's native code;
* real changes: a parameter changed by 0.1 %, another seed, a one-sample shift.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from flowtex.testing import DEFAULT_RMS_RTOL, GoldenMismatch, check_golden, compare_outputs, rms, run_graph_on_file

REPO = Path(__file__).resolve().parents[1]
GRAPHS = REPO / "graphs"
GOLDEN = REPO / "tests" / "golden"
ACCEL = (GRAPHS / "accel_preprocess.yaml", GRAPHS / "data" / "accel_demo.npz", GOLDEN / "accel_preprocess.npz")
NOISY = (GRAPHS / "multirate_feedback.yaml", GRAPHS / "data" / "accel_demo.npz", GOLDEN / "multirate_feedback.npz")


def load(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as d:
        return {k: d[k] for k in d.files}


@pytest.fixture(scope="module")
def native() -> dict[str, np.ndarray]:
    return run_graph_on_file(*ACCEL[:2])


@pytest.fixture(scope="module")
def generic(tmp_path_factory) -> dict[str, np.ndarray]:
    """accel_preprocess.yaml run with numba's generic x86-64 code (no FMA), in its own process."""
    out = tmp_path_factory.mktemp("generic") / "out.npz"
    code = ("import sys, numpy as np; from flowtex.testing import run_graph_on_file; "
            "np.savez(sys.argv[3], **run_graph_on_file(sys.argv[1], sys.argv[2]))")
    env = {**os.environ, "NUMBA_CPU_NAME": "generic", "PYTHONPATH": os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])}
    subprocess.run([sys.executable, "-c", code, str(ACCEL[0]), str(ACCEL[1]), str(out)], env=env, check=True, timeout=300)
    return load(out)


def spread(actual: dict[str, np.ndarray], expected: dict[str, np.ndarray]) -> float:
    """Largest |actual - expected| over all outputs, relative to that output's RMS."""
    return max(float(np.max(np.abs(actual[k] - expected[k]))) / rms(expected[k]) for k in expected)


# --- another CPU passes -------------------------------------------------------

def test_generic_cpu_code_gives_other_bits_within_the_default_tolerance(native, generic):
    differ = sum(int(np.sum(native[k] != generic[k])) for k in native)
    assert differ > 1000, "the generic build should round differently (no fused multiply-add)"
    assert compare_outputs(generic, native, exact=True)  # exact mode sees the difference
    assert compare_outputs(generic, native) == []
    # measured 2e-13 x RMS (benchmarks/golden_spread.py): the default sits orders of magnitude above
    assert spread(generic, native) < DEFAULT_RMS_RTOL / 1000


def test_generic_cpu_output_passes_the_golden_file_made_on_another_machine(generic):
    assert compare_outputs(generic, load(ACCEL[2])) == []


# --- real changes fail ----------------------------------------------------------

def test_a_parameter_changed_by_a_tenth_of_a_percent_fails():
    with pytest.raises(GoldenMismatch, match=r"output 'envelope': \d+ of 8000 values differ"):
        check_golden(*ACCEL, overrides={"highpass.cutoff_hz": 10.01})
    check_golden(*ACCEL, overrides={"highpass.cutoff_hz": 10.0})  # the same value still passes


def test_another_seed_fails():
    with pytest.raises(GoldenMismatch, match="output 'noise'"):
        check_golden(*NOISY, seed=2)
    check_golden(*NOISY)


@pytest.mark.parametrize("name", sorted(p.name for p in GOLDEN.glob("*.npz")))
def test_a_one_sample_shift_fails_for_every_output_of_every_example(name):
    golden = load(GOLDEN / name)
    for key, values in golden.items():
        if np.all(values == values[0]):
            continue  # constant outputs cannot show a shift
        late = np.concatenate([values[:1], values[:-1]])  # one tick late, first value repeated
        problems = compare_outputs({key: late}, {key: values})
        assert problems and "values differ" in problems[0], (name, key)


# --- the comparison rules -------------------------------------------------------

def test_tolerance_is_relative_to_each_outputs_rms():
    e = {"big": np.array([1e3, -1e3, 0.0]), "small": np.array([1e-3, -1e-3, 0.0])}
    scale_big, scale_small = rms(e["big"]), rms(e["small"])
    ok = {"big": e["big"] + 0.5 * DEFAULT_RMS_RTOL * scale_big, "small": e["small"] - 0.5 * DEFAULT_RMS_RTOL * scale_small}
    assert compare_outputs(ok, e) == []
    bad = {"big": e["big"], "small": e["small"] + np.array([0.0, 0.0, 2 * DEFAULT_RMS_RTOL * scale_small])}
    (problem,) = compare_outputs(bad, e)
    assert problem.startswith("output 'small': 1 of 3 values differ") and "first at (2,)" in problem
    assert compare_outputs(bad, e, rms_rtol=1e-6) == []


def test_nan_and_inf_must_stay_where_they_are():
    e = np.array([1.0, np.nan, np.inf, -2.0])
    assert compare_outputs({"y": e.copy()}, {"y": e}) == []
    for changed in ([1.0, 0.0, np.inf, -2.0], [np.nan, np.nan, np.inf, -2.0], [1.0, np.nan, -np.inf, -2.0], [1.0, np.nan, 1e308, -2.0]):
        assert compare_outputs({"y": np.array(changed)}, {"y": e}, rms_rtol=1.0), changed


def test_an_all_zero_output_must_stay_exactly_zero():
    assert compare_outputs({"y": np.array([0.0, 1e-300])}, {"y": np.zeros(2)})


def test_integer_and_boolean_outputs_compare_exactly():
    assert compare_outputs({"n": np.array([1, 2, 3])}, {"n": np.array([1, 2, 4])}, rms_rtol=1.0)
    assert compare_outputs({"b": np.array([True, False])}, {"b": np.array([True, True])}, rms_rtol=1.0)
    assert compare_outputs({"n": np.array([1, 2, 3])}, {"n": np.array([1, 2, 3])}) == []


def test_exact_mode_and_numpy_style_tolerances():
    e = {"y": np.array([1.0, 2.0, 3.0])}
    a = {"y": np.array([1.0, 2.0, 3.0 + 1e-12])}
    assert compare_outputs(a, e) == []
    assert "must be identical" in compare_outputs(a, e, exact=True)[0]
    assert compare_outputs(a, e, rms_rtol=0.0)  # no tolerance left: exact
    assert compare_outputs(a, e, rtol=1e-12, rms_rtol=0.0) == []
    assert compare_outputs(a, e, atol=2e-12, rms_rtol=0.0) == []
    assert compare_outputs(a, e, atol=1e-13, rms_rtol=0.0)


@pytest.mark.parametrize("bad", [{"rtol": -1.0}, {"atol": float("nan")}, {"rms_rtol": float("inf")}, {"atol": "1e-6"},
                                 {"rtol": True}])
def test_a_tolerance_that_is_no_finite_number_at_least_0_is_refused(bad):
    """rtol=-1 was accepted and made every comparison stricter than exact, silently."""
    e = {"y": np.array([1.0, 2.0])}
    with pytest.raises(ValueError, match=rf"compare_outputs: {next(iter(bad))} must be a finite number >= 0"):
        compare_outputs(e, e, **bad)


@pytest.fixture
def numba_registries_loaded() -> None:
    """numba's CPU target with its extra registries loaded (what its first compile in a process imports).

    The pytester fixture removes, at its teardown, every module imported after its setup, but not what those modules
    registered in numba: a module numba first imports inside the inner run would be imported and registered again by
    the process's next compile ("duplicate registration for PolynomialType", every later compile of that xdist
    worker failing). Requested before pytester, so that the modules are in its snapshot."""
    from numba.core.registry import cpu_target

    cpu_target.target_context.refresh()


def test_a_golden_mismatch_shows_its_message_not_a_long_traceback(numba_registries_loaded, pytester, monkeypatch):
    """What pytest prints for a failing golden test (issue 9): the message, in a few lines. The inner pytest runs in
    this process (pytester): its report is the point, and it loads flowtex's plugin from its entry point as a process
    of its own would."""
    golden = pytester.path / "accel.npz"
    tampered = load(ACCEL[2])
    tampered["envelope"] = tampered["envelope"] * 1.01
    np.savez(golden, **tampered)
    test = pytester.path / "test_user_graph.py"
    test.write_text(f"def test_graph(golden):\n    golden.check({str(ACCEL[0])!r}, {str(ACCEL[1])!r}, {str(golden)!r})\n")
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)  # a user's plain pytest run, not an xdist worker's
    run = pytester.runpytest_inprocess("-q", "-p", "no:cacheprovider", str(test))
    stdout = run.stdout.str()
    assert run.ret == 1, stdout
    failure = stdout[stdout.index("_ test_graph _"):stdout.index("short test summary")]
    assert "output 'envelope': 8000 of 8000 values differ" in failure
    assert "testing.py" not in failure  # flowtex's own frames are hidden
    assert len(failure.splitlines()) < 20, failure
