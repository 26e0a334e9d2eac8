"""The on-disk memo of filter designs returns scipy's coefficients bit for bit, warm or cold, damaged or not."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
from scipy import signal

from flowtex.dsp import design_memo
from flowtex.dsp.filter_design import butterworth_sos

CASES = [("lowpass", 4, [100.0], 1000.0), ("highpass", 3, [10.0], 1000.0), ("bandpass", 2, [50.0, 200.0], 1000.0),
         ("bandstop", 5, [120.0, 180.0], 2000.0)]


def scipy_sos(kind, order, cut, rate):
    return signal.butter(order, cut if len(cut) == 2 else cut[0], btype=kind, fs=rate, output="sos")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(tmp_path))
    return tmp_path / design_memo.FOLDER


@pytest.mark.parametrize("kind,order,cut,rate", CASES)
def test_cold_and_warm_equal_scipy_bit_for_bit(cache, kind, order, cut, rate):
    cold = butterworth_sos(kind, order, cut, rate)
    assert len(list(cache.glob("*.npz"))) == 1
    warm = butterworth_sos(kind, order, cut, rate)
    expected = scipy_sos(kind, order, cut, rate)
    assert np.array_equal(cold, expected) and np.array_equal(warm, expected)


def test_different_arguments_are_different_designs(cache):
    a = butterworth_sos("lowpass", 4, [100.0], 1000.0)
    b = butterworth_sos("lowpass", 4, [101.0], 1000.0)
    assert not np.array_equal(a, b) and len(list(cache.glob("*.npz"))) == 2


@pytest.mark.parametrize("damage", ["truncated", "other key", "nan", "wrong shape"])
def test_a_damaged_entry_is_recomputed_and_rewritten(cache, damage):
    butterworth_sos("lowpass", 4, [100.0], 1000.0)
    (entry,) = cache.glob("*.npz")
    if damage == "truncated":
        entry.write_bytes(entry.read_bytes()[:40])
    else:
        with np.load(entry) as f:
            key, coef = str(f["key"]), f["coef"].copy()
        if damage == "other key":
            key = key.replace("100.0", "900.0")
            coef[:] = 0.5
        elif damage == "nan":
            coef[0, 0] = np.nan
        else:
            coef = coef[:1]
        with open(entry, "wb") as out:
            np.savez(out, key=np.array(key), coef=coef)
    got = butterworth_sos("lowpass", 4, [100.0], 1000.0)
    assert np.array_equal(got, scipy_sos("lowpass", 4, [100.0], 1000.0))
    with np.load(entry) as f:  # written again with the right coefficients
        assert np.array_equal(f["coef"], got)


def test_an_unusable_cache_folder_only_costs_the_import(tmp_path, monkeypatch):
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("FLOWTEX_CACHE_DIR", str(blocker))
    assert np.array_equal(butterworth_sos("highpass", 2, [20.0], 500.0), scipy_sos("highpass", 2, [20.0], 500.0))


def test_a_warm_design_does_not_import_scipy_signal(cache):
    butterworth_sos("lowpass", 4, [100.0], 1000.0)  # memoized here; a new process designs it warm, then another one cold
    code = ("import sys; from flowtex.dsp.filter_design import butterworth_sos; "
            "s = butterworth_sos('lowpass', 4, [100.0], 1000.0); print('scipy.signal' in sys.modules, s.shape); "
            "s = butterworth_sos('lowpass', 4, [110.0], 1000.0); print('scipy.signal' in sys.modules, s.shape)")
    env = {"FLOWTEX_CACHE_DIR": str(cache.parent), "PATH": "/usr/bin:/bin"}
    warm, cold = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True).stdout.split("\n")[:2]
    assert warm.split()[0] == "False" and cold.split()[0] == "True"  # the cold design shows the check sees the import
