"""Tap library files: round trip, sorting/padding, and an error naming file and field for each malformation."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from flowtex.datasets.taps import synthetic_tap_library
from flowtex.errors import DataError
from flowtex.io.taplib import read_tap_library, write_tap_library
from flowtex.models.taps import TapLibrary, resample_tap_library, spectral_centroid


def test_round_trip_is_exact(tmp_path):
    lib = synthetic_tap_library()
    path = write_tap_library(tmp_path / "taps.json", lib, notes="synthetic")
    back = read_tap_library(path)
    np.testing.assert_array_equal(back.speeds, lib.speeds)
    np.testing.assert_array_equal(back.transients, lib.transients)
    assert back.sample_rate_hz == lib.sample_rate_hz and back.name == lib.name


def test_taps_are_sorted_and_short_ones_zero_padded(tmp_path):
    doc = {"format": "flowtex-tap-library", "version": 1, "sample_rate_hz": 500,
           "taps": [{"speed": 80, "acceleration": [1, 2, 3]}, {"speed": 30.5, "acceleration": [4]}]}
    path = tmp_path / "t.json"
    path.write_text(json.dumps(doc))
    lib = read_tap_library(path)
    np.testing.assert_array_equal(lib.speeds, [30.5, 80])
    np.testing.assert_array_equal(lib.transients, [[4, 0, 0], [1, 2, 3]])
    assert lib.name == "t" and lib.sample_rate_hz == 500.0


GOOD = {"format": "flowtex-tap-library", "version": 1, "sample_rate_hz": 1000,
        "taps": [{"speed": 20, "acceleration": [1, 2]}, {"speed": 60, "acceleration": [3, 4]}]}


def _with(change):
    doc = json.loads(json.dumps(GOOD))
    change(doc)
    return doc


@pytest.mark.parametrize("doc,field", [
    (_with(lambda d: d.update(format="other")), "'format'"),
    (_with(lambda d: d.update(version=2)), "'version'"),
    (_with(lambda d: d.pop("sample_rate_hz")), "'sample_rate_hz'"),
    (_with(lambda d: d.update(sample_rate_hz=-1)), "'sample_rate_hz'"),
    (_with(lambda d: d.update(sample_rate_hz="fast")), "'sample_rate_hz'"),
    (_with(lambda d: d.update(taps=[])), "'taps'"),
    (_with(lambda d: d["taps"][1].update(speed=-3)), "'taps[1].speed'"),
    (_with(lambda d: d["taps"][1].update(speed=20)), "'taps[1].speed'"),
    (_with(lambda d: d["taps"][0].pop("acceleration")), "'taps[0].acceleration'"),
    (_with(lambda d: d["taps"][0].update(acceleration=[1, "x"])), "'taps[0].acceleration[1]'"),
    (_with(lambda d: d["taps"][0].update(accel=[1])), "'taps[0].accel'"),
    (_with(lambda d: d.update(speed_unit="m/s")), "'speed_unit'"),
    (_with(lambda d: d.update(sample_rate=1000)), "'sample_rate'"),
])
def test_malformed_files_name_file_and_field(tmp_path, doc, field):
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(doc))
    with pytest.raises(DataError) as err:
        read_tap_library(path)
    assert str(path) in str(err.value)
    assert field in str(err.value)


def test_invalid_json_and_missing_file_are_data_errors(tmp_path):
    path = tmp_path / "broken.json"
    path.write_text('{"format": "flowtex-tap-library",\n "version": 1,,}')
    with pytest.raises(DataError, match=r"broken\.json:2:\d+: not valid JSON"):
        read_tap_library(path)
    with pytest.raises(DataError, match="not found"):
        read_tap_library(tmp_path / "nope.json")


def test_unknown_top_level_field_suggests_the_right_name(tmp_path):
    path = tmp_path / "typo.json"
    path.write_text(json.dumps(_with(lambda d: d.update(sample_rate_hzz=1))))
    with pytest.raises(DataError, match="did you mean 'sample_rate_hz'"):
        read_tap_library(path)


def test_synthetic_library_follows_its_formula():
    lib = synthetic_tap_library(speeds=(100.0, 25.0), sample_rate_hz=2000.0, duration_s=0.05, freq_hz=200.0,
                                decay_s=0.01, gain=0.3, stiffening=0.5)
    assert lib.length == 100 and lib.duration_s == pytest.approx(0.05)
    np.testing.assert_array_equal(lib.speeds, [25.0, 100.0])
    t = 37 / 2000.0
    for k, v in enumerate(lib.speeds):
        f = 200.0 * (1 + 0.5 * v / 100.0)
        assert lib.transients[k, 37] == pytest.approx(0.3 * v * math.exp(-t / 0.01) * math.sin(2 * math.pi * f * t), rel=1e-12)


def test_library_validation():
    with pytest.raises(ValueError, match="strictly increasing"):
        TapLibrary(np.array([50.0, 20.0]), np.zeros((2, 3)), 1000.0)
    with pytest.raises(ValueError, match="shape"):
        TapLibrary(np.array([50.0]), np.zeros((2, 3)), 1000.0)


def test_resampling_keeps_duration_and_a_slow_sinusoid():
    fs1, fs2 = 2000.0, 1000.0
    t1 = np.arange(200) / fs1
    lib = TapLibrary(np.array([50.0]), np.sin(2 * np.pi * 20 * t1)[None, :], fs1)
    out = resample_tap_library(lib, fs2)
    assert out.sample_rate_hz == fs2 and out.length == 100
    t2 = np.arange(100) / fs2
    # away from the edges (filter start-up) the 20 Hz sinusoid is reproduced at the new rate
    np.testing.assert_allclose(out.transients[0, 20:80], np.sin(2 * np.pi * 20 * t2[20:80]), atol=2e-3)


def test_spectral_centroid_of_a_decaying_sinusoid_is_near_its_frequency():
    lib = synthetic_tap_library(speeds=(20.0, 200.0), sample_rate_hz=10000.0, duration_s=0.1, freq_hz=800.0,
                                decay_s=0.02, stiffening=0.0)
    assert spectral_centroid(lib) == pytest.approx(800.0, rel=0.1)
    soft = synthetic_tap_library(speeds=(20.0, 200.0), sample_rate_hz=10000.0, freq_hz=100.0, stiffening=0.0)
    assert spectral_centroid(soft) < spectral_centroid(lib)
