"""``flowtex resample``: the issue's 1 kHz -> 800 Hz tone example, rates, lengths, vector signals, errors.

References: analytic tones (least-squares amplitude and phase at the output
times k / 800 s), flowtex.dsp.resample.resample_signal for per-signal values.
"""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.dsp.resample import resample_signal
from flowtex.io.recordings import load_recording, save_recording


def tone_fit(y: np.ndarray, rate: float, freqs, lo: int, hi: int) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares amplitude and phase of cos(2 pi f t + phase) at each f over samples lo:hi."""
    t = np.arange(lo, hi) / rate
    cols = [c for f in freqs for c in (np.cos(2 * np.pi * f * t), -np.sin(2 * np.pi * f * t))]
    coef, *_ = np.linalg.lstsq(np.stack(cols, axis=1), y[lo:hi], rcond=None)
    c = coef[0::2] + 1j * coef[1::2]
    return np.abs(c), np.angle(c)


def test_1000_to_800_hz_keeps_tones_removes_450_hz_and_stays_aligned(tmp_path, capsys) -> None:
    t = np.arange(3000) / 1000.0
    freqs, amps, phases = [50.0, 170.0, 310.0], [1.0, 0.7, 0.4], [0.1, 1.2, -2.0]
    tones = sum(a * np.cos(2 * np.pi * f * t + p) for f, a, p in zip(freqs, amps, phases, strict=True))
    x = tones + np.cos(2 * np.pi * 450.0 * t)
    save_recording(tmp_path / "in.npz", {"acc": x, "vec": np.stack([x, -x], axis=1)}, rate=1000.0)
    assert main(["resample", str(tmp_path / "in.npz"), "--rate", "800", "-o", str(tmp_path / "out.npz")]) == 0
    rec = load_recording(tmp_path / "out.npz")
    assert rec.rate == 800.0
    y = rec.arrays["acc"]
    assert y.shape == (2400,) and rec.arrays["vec"].shape == (2400, 2)
    amp, ph = tone_fit(y, 800.0, freqs + [350.0], 150, 2250)  # 450 Hz would alias to 350 Hz
    assert np.all(np.abs(20 * np.log10(amp[:3] / amps)) <= 0.1)
    assert 20 * np.log10(amp[3]) <= -60.0
    np.testing.assert_allclose(ph[:3], phases, atol=1e-3)  # aligned: zero delay
    np.testing.assert_allclose(rec.arrays["vec"], np.stack([y, -y], axis=1), rtol=0, atol=1e-12)
    assert "x 4/5" in capsys.readouterr().out


@pytest.mark.parametrize("rate_in,rate_out,n", [(800.0, 1000.0, 333), (10000.0, 1000.0, 1234), (2500.0, 1000.0, 7)])
def test_rates_and_lengths_with_from_rate_and_csv(tmp_path, rate_in, rate_out, n) -> None:
    rng = np.random.default_rng(n)
    pos = rng.standard_normal((n, 3))
    save_recording(tmp_path / "in.csv", {"position": pos})  # states no rate
    out = tmp_path / "out.csv"
    assert main(["resample", str(tmp_path / "in.csv"), "--rate", str(rate_out), "--from-rate", str(rate_in), "-o", str(out)]) == 0
    rec = load_recording(out)
    assert rec.rate == rate_out
    assert rec.arrays["position"].shape == (int(np.floor(n * rate_out / rate_in + 0.5)), 3)
    np.testing.assert_allclose(rec.arrays["position"], resample_signal(pos, rate_in, rate_out), rtol=0, atol=1e-12)


def test_no_rate_and_no_from_rate_is_a_one_line_error(tmp_path, capsys) -> None:
    save_recording(tmp_path / "in.npz", {"x": np.zeros(10)})
    assert main(["resample", str(tmp_path / "in.npz"), "--rate", "800", "-o", str(tmp_path / "out.npz")]) == 1
    err = capsys.readouterr().err.strip()
    assert "in.npz" in err and "--from-rate" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out.npz").exists()


@pytest.mark.parametrize("args,match", [(["--rate", "1000.5"], "not p/q"), (["--rate", "800", "--from-rate", "500"], "states 1000 Hz")])
def test_bad_rates_are_one_line_errors(tmp_path, capsys, args, match) -> None:
    save_recording(tmp_path / "in.npz", {"x": np.zeros(10)}, rate=1000.0)
    assert main(["resample", str(tmp_path / "in.npz"), *args, "-o", str(tmp_path / "out.npz")]) == 1
    err = capsys.readouterr().err.strip()
    assert match in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out.npz").exists()


def test_nan_signal_is_named_and_nothing_is_written(tmp_path, capsys) -> None:
    x = np.zeros(10)
    x[3] = np.nan
    save_recording(tmp_path / "in.npz", {"good": np.zeros(10), "bad": x}, rate=1000.0)
    assert main(["resample", str(tmp_path / "in.npz"), "--rate", "500", "-o", str(tmp_path / "out.npz")]) == 1
    assert "'bad'" in capsys.readouterr().err
    assert not (tmp_path / "out.npz").exists()


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".h5"])
def test_the_units_a_recording_states_are_kept(tmp_path, suffix) -> None:
    """A resampled recording states the units its source stated (they were dropped before, so a speed stated in m/s
    lost the statement that makes `flowtex run` and the fits refuse it for an input in mm/s)."""
    if suffix == ".h5":
        pytest.importorskip("h5py")
    src = tmp_path / f"in{suffix}"
    out = tmp_path / f"out{suffix}"
    n = 2000
    units = {"speed": "m/s", "normal_force": "N"}
    save_recording(src, {"speed": np.full(n, 0.1), "normal_force": np.ones(n), "trigger": np.zeros(n)}, rate=1000.0, units=units)
    assert main(["resample", str(src), "--rate", "2000", "-o", str(out)]) == 0
    got = load_recording(out)
    assert got.rate == 2000.0 and got.units == units


@pytest.mark.parametrize(("rate_in", "rate_out"), [(1000.0, 2000.0), (1000.0, 300.0), (1000.0, 44100.0), (2500.0, 1000.0)])
def test_flags_and_indices_keep_their_values_and_their_edges(tmp_path, capsys, rate_in, rate_out) -> None:
    """A 0/1 contact flag and a 0..2 surface index are held, not filtered: they keep their values (a filter rang to
    -0.13 and 1.13 around each step), and each change lands on the output sample nearest to it, within half an
    output period; a waveform beside them is still filtered."""
    rng = np.random.default_rng(3)
    n = 3000
    flag = np.zeros(n)
    for start in rng.integers(0, n - 200, 6):
        flag[start:start + rng.integers(20, 200)] = 1.0
    index = np.repeat(rng.integers(0, 3, 30), n // 30).astype(float)
    wave = np.sin(2 * np.pi * 37.0 * np.arange(n) / rate_in)
    src, out = tmp_path / "in.npz", tmp_path / "out.npz"
    save_recording(src, {"in_contact": flag, "surface": index, "wave": wave}, rate=rate_in)
    assert main(["resample", str(src), "--rate", str(rate_out), "-o", str(out)]) == 0
    assert "held, not filtered (whole numbers of at most 16 values): in_contact, surface" in capsys.readouterr().out
    back = load_recording(out).arrays
    np.testing.assert_array_equal(back["wave"], resample_signal(wave, rate_in, rate_out))
    for name, x in (("in_contact", flag), ("surface", index)):
        y = back[name]
        assert len(y) == len(back["wave"]) and set(np.unique(y)) <= set(np.unique(x))
        # independently of the index arithmetic: the input samples before and after each output time, in seconds
        t_out, t_in = np.arange(len(y)) / rate_out, np.arange(n) / rate_in
        after = np.clip(np.searchsorted(t_in, t_out), 1, n - 1)
        d_before, d_after = t_out - t_in[after - 1], t_in[after] - t_out
        nearest = np.where(d_after < d_before, x[after], x[after - 1])
        tie = np.isclose(d_before, d_after, rtol=0, atol=1e-12)  # halves go to the later sample; either is nearest
        assert np.all((y == nearest) | (tie & (y == x[after]))), name


def test_a_short_recordings_integer_ramps_stay_ramps(tmp_path, capsys) -> None:
    """Time 0, 1, ..., 9 s and a position in whole mm are whole numbers of at most 16 values, but they change at every
    step: waveforms, filtered (exact for a ramp), not held into staircases (the held time column did not increase, and
    the output could not be read back)."""
    src, out = tmp_path / "short.npz", tmp_path / "out.npz"
    save_recording(src, {"time": np.arange(10.0), "position": np.arange(10.0) * 3.0, "flag": np.r_[np.zeros(6), np.ones(4)]},
                   rate=1.0)
    assert main(["resample", str(src), "--rate", "2", "-o", str(out)]) == 0
    assert "held, not filtered (whole numbers of at most 16 values): flag" in capsys.readouterr().out
    back = load_recording(out).arrays  # reads: the time column increases
    np.testing.assert_allclose(back["time"], np.arange(20) / 2.0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(back["position"], 3.0 * np.arange(20) / 2.0, rtol=0, atol=1e-12)
    assert set(np.unique(back["flag"])) == {0.0, 1.0}
