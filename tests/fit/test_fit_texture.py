"""flowtex fit texture against ground truth (flowtex.datasets), end to end through the CLI, and its bad-input errors."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import free_exploration
from flowtex.dsp.arma import arma_output_variance
from flowtex.dsp.arma_estimate import burg_ar
from flowtex.fit.quality import model_lsd_db, models_at, set_lsd_db
from flowtex.fit.texture import TextureOptions, fit_texture, preprocess
from flowtex.io.hatt import read_hatt_xml
from flowtex.io.modelset import load_model_set
from flowtex.io.recordings import save_recording

RATE = 1000.0


@pytest.fixture(scope="module")
def exploration():
    # The 60 s of plateaus (1-2 s each, 3 % wobble) on the 6/4 default surface, 1 % sensor noise, 4 spikes.
    return free_exploration(60.0, RATE, seed=5, outliers=4)


def test_free_exploration_matches_oracle(exploration):
    """Median LSD of the fitted set at the plateau points within 0.5 dB of an oracle told the true plateaus.

    60 s hold ~40 plateaus, as the issue states. The
    tolerance (0.5 dB) is the issue's: both the fit and the oracle lose
    accuracy the same way on shorter pieces (LSD ~ 1/sqrt(samples)), so the
    difference between them is what segmentation and set assembly cost. The
    oracle fits a Burg AR(20) to each true plateau of the same preprocessed signal.
    """
    a = exploration.arrays
    fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(6, 4)))
    truth = exploration.truth["surface"]
    plateaus = exploration.truth["plateaus"]
    sp = np.array([p.speed for p in plateaus])
    fo = np.array([p.force for p in plateaus])
    ours = set_lsd_db(fit.model_set, truth, sp, fo)
    x, _ = preprocess(a["accel"], RATE)
    oracle = []
    for p, true_model in zip(plateaus, models_at(truth, sp, fo), strict=True):
        seg = x[p.start:p.stop]
        ar, _ = burg_ar(seg, 20)
        ar = np.asarray(ar)
        var = np.var(seg) / arma_output_variance(ar, np.array([1.0]), 1.0, 1.0)
        oracle.append(model_lsd_db(ar, np.array([1.0]), 1.0, var, true_model, RATE))
    assert np.median(ours) <= np.median(oracle) + 0.5, (np.median(ours), np.median(oracle))
    assert fit.clipped == 4  # each 20-RMS spike clipped, nothing else (8 robust sd: a Gaussian never gets there)
    # silent corners and maxima, as HaTT
    ms = fit.model_set
    silent = ms.variance == 0
    assert np.all((ms.speeds[silent] == 0) | (ms.forces[silent] == 0))
    assert ms.max_speed == pytest.approx(max(pc.speed for pc in fit.pieces))
    assert ms.max_force == pytest.approx(max(pc.force for pc in fit.pieces))


def test_cli_end_to_end_renders(tmp_path, capsys):
    """3-axis accel (DFT321) + speed from position + auto order -> JSON + XML that read back and render in hatt_texture."""
    rec = free_exploration(8.0, RATE, seed=2, axes=3, plateau_s=(1.5, 2.0))
    path = rec.save(tmp_path / "rec.npz")
    out = tmp_path / "surface.json"
    xml = tmp_path / "surface.xml"
    code = main(["fit", "texture", str(path), "--accel", "accel", "--position", "position", "--normal", "normal",
                 "--force", "normal_force", "--max-order", "3", "-o", str(out), "--xml", str(xml), "--report", str(tmp_path / "rep")])
    printed = capsys.readouterr().out
    assert code == 0, printed
    assert "GFC" in printed and "LSD" in printed and "power dB" in printed
    ms = load_model_set(out)
    back = read_hatt_xml(xml)
    # written with repr: the reader gets the same numbers (its printed precision is exact)
    np.testing.assert_array_equal(back.ar_lsf, ms.ar_lsf)
    np.testing.assert_array_equal(back.variance, ms.variance)
    np.testing.assert_array_equal(back.triangles, ms.triangles)
    assert (tmp_path / "rep" / "report.md").exists() and (tmp_path / "rep" / "plane.png").exists()
    from flowtex.fit.friction import store_mu
    from flowtex.graph.compiled import load_graph
    from tests.conftest import REPO

    store_mu(out, 0.3)  # what `flowtex fit friction --into` does; coulomb_friction reads it from the set
    assert load_model_set(out).mu == 0.3
    graph = load_graph(REPO / "graphs" / "hatt_texture.yaml", {"lookup.models": str(out), "friction.models": str(out)})
    n = 3000
    res = graph.run({"position": rec.arrays["position"][:n], "normal_force": rec.arrays["normal_force"][:n],
                     "normal": rec.arrays["normal"][:n]})
    vib = res["vibration"]
    assert np.all(np.isfinite(vib)) and np.std(vib[500:]) > 0.1 * np.std(rec.truth["clean"][500:n])


def _bad(tmp_path, capsys, arrays, rate=RATE, extra=()):
    path = tmp_path / "bad.npz"
    save_recording(path, arrays, rate)
    out = tmp_path / "bad_surface.json"
    code = main(["fit", "texture", str(path), "--speed", "speed", "--max-order", "4", "-o", str(out), *extra])
    err = capsys.readouterr().err.strip()
    assert code == 1 and not out.exists()
    assert len(err.splitlines()) == 1, err
    return err


def test_bad_inputs(tmp_path, capsys):
    rng = np.random.default_rng(0)
    n = 4000
    good = {"accel": rng.standard_normal(n), "speed": np.full(n, 100.0), "normal_force": np.full(n, 1.0)}
    assert "no signal 'accel'" in _bad(tmp_path, capsys, {k: v for k, v in good.items() if k != "accel"})
    assert "shape (4000, 2)" in _bad(tmp_path, capsys, {**good, "accel": np.zeros((n, 2))})
    nan = good["accel"].copy()
    nan[[10, 20]] = np.nan
    assert "2 NaN/inf sample(s) (at sample 10, 20)" in _bad(tmp_path, capsys, {**good, "accel": nan})
    assert "no contact anywhere" in _bad(tmp_path, capsys, {**good, "normal_force": np.zeros(n)})
    assert "is constant" in _bad(tmp_path, capsys, {**good, "accel": np.ones(n)})
    assert "states no sample rate; pass --from-rate HZ" in _bad(tmp_path, capsys, good, rate=None)
    # a CSV-like recording with a time column (s) but no rate: the message names the rate its steps give
    timed = {**good, "time": np.arange(n) / 800.0}
    assert "pass --from-rate 800 (the median step of its 'time' column, 0.00125 s)" in _bad(tmp_path, capsys, timed, rate=None)
    assert "--from-rate is 500" in _bad(tmp_path, capsys, good, extra=("--from-rate", "500"))
    assert "recording too short" in _bad(tmp_path, capsys, {k: v[:300] for k, v in good.items()})
    assert "too short for order" in _bad(tmp_path, capsys, {k: v[:800] for k, v in good.items()}, extra=("--order", "40,38"))


def test_no_speed_option_names_the_signals_the_file_has(tmp_path, capsys):
    """Neither --speed nor --position: the one line says which signals the recording holds, so the user picks one."""
    rng = np.random.default_rng(0)
    n = 4000
    path = tmp_path / "rec.npz"
    save_recording(path, {"accel": rng.standard_normal(n), "speed": np.full(n, 100.0), "normal_force": np.full(n, 1.0),
                          "position": np.zeros((n, 3))}, RATE)
    out = tmp_path / "s.json"
    code = main(["fit", "texture", str(path), "-o", str(out)])
    err = capsys.readouterr().err.strip()
    assert code == 1 and not out.exists() and len(err.splitlines()) == 1, err
    assert "--speed S (mm/s) or --position P" in err and "the file has: accel, normal_force, position, speed" in err, err


def test_render_rate_resamples_every_fitted_model(tmp_path, capsys):
    """--render-rate 2000: the written set runs at 2 kHz and each model keeps the 1 kHz fit's spectrum (the issue's 0.5 dB).

    Reference: the same fit written at the recording's rate. Both sets are read back and every measured model's
    physical PSD (rebuilt from its stored LSFs, as texture_lookup renders it) compared up to 0.9 x 500 Hz.
    """
    from flowtex.dsp.arma import arma_psd
    from flowtex.dsp.lsf import lsf_to_poly_new
    from flowtex.dsp.spectral import lsd_db

    rec = free_exploration(8.0, RATE, seed=4, plateau_s=(1.5, 2.0))
    path = rec.save(tmp_path / "rec.npz")
    common = [str(path), "--speed", "speed", "--order", "6,4"]
    assert main(["fit", "texture", *common, "-o", str(tmp_path / "native.json")]) == 0
    assert main(["fit", "texture", *common, "--render-rate", "2000", "-o", str(tmp_path / "2k.json")]) == 0
    assert "resampled 1000 Hz -> 2000 Hz" in capsys.readouterr().out
    native, fast = load_model_set(tmp_path / "native.json"), load_model_set(tmp_path / "2k.json")
    assert fast.sample_rate == 2000.0 and fast.num_models == native.num_models
    np.testing.assert_array_equal(fast.speeds, native.speeds)
    f = np.linspace(0.0, 0.45 * RATE, 2001)
    for m in np.flatnonzero(native.variance > 0):
        s1 = arma_psd(lsf_to_poly_new(native.ar_lsf[m]), lsf_to_poly_new(native.ma_lsf[m]), native.gain[m], native.variance[m], f, RATE)
        s2 = arma_psd(lsf_to_poly_new(fast.ar_lsf[m]), lsf_to_poly_new(fast.ma_lsf[m]), fast.gain[m], fast.variance[m], f, 2000.0)
        assert lsd_db(s2, s1, f, min_freq_hz=0.0) <= 0.5


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".h5"])
def test_generated_recordings_state_their_units_as_a_rig_would(tmp_path, suffix):
    """A saved generated recording states each signal's unit (flowtex.datasets.SIGNAL_UNITS), so the chain run on it
    meets the stated-unit checks a real rig's file meets; the unit vector ``normal`` states none."""
    from flowtex.io.recordings import load_recording

    if suffix == ".h5":
        pytest.importorskip("h5py")
    rec = free_exploration(1.0, RATE, seed=1)
    back = load_recording(rec.save(tmp_path / f"rec{suffix}"))
    assert back.units == {"accel": "m/s^2", "position": "mm", "normal_force": "N", "speed": "mm/s"}
