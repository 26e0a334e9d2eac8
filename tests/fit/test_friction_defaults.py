"""Issue 18 (5): fit friction's defaults -- HaTT's line through the origin, r2, the warning, and --into with an offset."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import friction_session
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.fit.friction import LOW_R2, fit_friction
from flowtex.io.modelset import load_model_set, save_model_set
from flowtex.io.recordings import save_recording


def _independent(seed=0, n=20000):
    """Tangential force independent of the normal force (as in issue 18's real recordings): 0.3 N +- 10 %, N = 1.2 +- 0.4 N."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / 1000.0
    normal = 1.2 + 0.4 * np.sin(2 * np.pi * 0.23 * t) + 0.01 * rng.standard_normal(n)
    tangential = 0.3 * (1 + 0.1 * rng.standard_normal(n))
    return normal, tangential


def test_default_is_the_line_through_the_origin():
    """Coulomb data: no warning, r2 high. With an offset b the default answer is the origin line's mu + b sum N / sum N^2."""
    rec = friction_session(mu=0.4, duration_s=20.0, seed=3, offset=0.05, spikes=25, lifts=4)
    n, t = rec.arrays["normal_force"], rec.arrays["tangential_force"]
    fit = fit_friction(n, t)
    assert fit.method.endswith("through the origin") and fit.offset == 0.0
    m = n >= 0.1
    biased = 0.4 + 0.05 * n[m].sum() / (n[m] ** 2).sum()  # least squares through the origin of T = 0.4 N + 0.05
    assert fit.mu == pytest.approx(biased, rel=0.03)  # friction_session's 3 % (10 % noise, stiction spikes)
    assert fit.r2 > 0.8 and fit.warning is None  # N explains T: 10 % multiplicative noise leaves r2 ~ 0.9
    clean = fit_friction(*(friction_session(mu=0.4, duration_s=20.0, seed=3).arrays[k] for k in ("normal_force", "tangential_force")))
    assert clean.mu == pytest.approx(0.4, rel=0.03) and clean.warning is None


def test_offset_is_opt_in_and_recovered():
    rec = friction_session(mu=0.4, duration_s=20.0, seed=5, offset=0.05, spikes=25, lifts=4)
    fit = fit_friction(rec.arrays["normal_force"], rec.arrays["tangential_force"], offset=True)
    assert fit.method.endswith("with offset")
    assert fit.mu == pytest.approx(0.4, rel=0.03) and fit.offset == pytest.approx(0.05, abs=0.01)
    assert fit.offset_ci[0] > 0.0 and fit.warning is None


def test_normal_force_explaining_nothing_warns_and_mu_is_the_force_ratio():
    """Correlation ~0: mu near the force ratio (HaTT's answer), r2 ~ 0, and a warning naming --offset yes."""
    normal, tangential = _independent()
    fit = fit_friction(normal, tangential)
    assert fit.r2 < 0.01 < LOW_R2
    ratio = tangential.sum() / normal.sum()
    # the origin line's slope is sum(NT)/sum(N^2) = ratio * mean(N)^2/mean(N^2) = ratio / (1 + 0.4^2/2/1.2^2) ~ 0.947 ratio
    assert fit.mu == pytest.approx(ratio * np.mean(normal) ** 2 / np.mean(normal ** 2), rel=0.01)
    assert fit.mu == pytest.approx(ratio, rel=0.1)
    assert fit.warning is not None and "explains only" in fit.warning and "--offset yes" in fit.warning
    # the offset model puts the force in b and says so, naming the origin line as the alternative
    off = fit_friction(normal, tangential, offset=True)
    assert abs(off.mu) < 0.01 and off.offset == pytest.approx(0.3, rel=0.02)
    assert off.warning is not None and "--offset no" in off.warning


def test_cli_prints_r2_and_the_warning_and_refuses_to_drop_an_offset(tmp_path, capsys):
    normal, tangential = _independent(seed=1, n=5000)
    rec = tmp_path / "flat.npz"
    save_recording(rec, {"normal_force": normal, "tangential_force": tangential}, 1000.0)
    surface = save_model_set(synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2, mu=None),
                             tmp_path / "s.json")
    args = ["fit", "friction", str(rec), "--force", "normal_force", "--friction-force", "tangential_force",
            "-o", str(tmp_path / "mu.json")]
    assert main(args) == 0
    printed = capsys.readouterr().out
    assert "r2" in printed and "warning: the normal force explains only" in printed
    doc = json.loads((tmp_path / "mu.json").read_text())
    assert doc["r2"] < LOW_R2 and "explains only" in doc["warning"]
    assert main(args + ["--offset", "yes", "--into", str(surface)]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "offset" in err and "--into" in err, err
    assert load_model_set(surface).mu is None  # nothing stored


def test_cli_without_force_options_lists_the_signals(tmp_path, capsys):
    """fit friction without --force/--friction-force said which options to give but not what the file holds (fit
    texture's missing --speed lists them)."""
    normal, tangential = _independent(seed=2, n=2000)
    rec = tmp_path / "f.npz"
    save_recording(rec, {"normal_force": normal, "tangential_force": tangential}, 1000.0)
    assert main(["fit", "friction", str(rec), "-o", str(tmp_path / "mu.json")]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "--friction-force" in err and err.endswith("the file has: normal_force, tangential_force")
    assert not (tmp_path / "mu.json").exists()
