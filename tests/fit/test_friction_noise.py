"""fit friction under friction noise that grows with the normal force: rejected samples, planted stiction, mu, mu_ci.

Ground truth: flowtex.datasets.dragging.stiction_drag (mu, the planted spikes' samples, the noise's standard
deviation and tail) and flowtex.datasets.resonant.textured_exploration (mu, friction noise proportional to the
force, no spike). The rule rejects a sample whose standardised residual is beyond 4.685 scales: clean noise puts
flowtex.dsp.hetero.false_rejection_rate(dof) of its samples there (2.8e-6 Gaussian, 0.39 % Student t5).
"""

from __future__ import annotations

import functools
import json

import numpy as np
import pytest
from scipy import stats

from flowtex.cli import main
from flowtex.datasets.dragging import stiction_drag
from flowtex.datasets.resonant import textured_exploration
from flowtex.dsp.hetero import false_rejection_rate, irls_line_hetero
from flowtex.fit.friction import fit_friction

MU = 0.4
T19 = stats.t.ppf(0.975, 19)   # the batch-means interval's t quantile (20 blocks)


@functools.cache
def _drag_fit(seed: int):
    """stiction_drag(mu=MU, seed=seed) with its defaults (20 spikes, 5 % drift) and its fit: the planted-stiction test
    and the mu test both check seeds 0-2, each its own assertions on one fit."""
    rec = stiction_drag(mu=MU, seed=seed)
    return rec, fit_friction(rec.arrays["normal_force"], rec.arrays["tangential_force"])


def _se(fit) -> float:
    """The fit's standard error of mu, back from its 95 % interval (batch means: t with 19 degrees of freedom; the
    asymptotic interval's t quantile with 20 000 degrees of freedom is smaller, so this SE errs on the wide side)."""
    return (fit.mu_ci[1] - fit.mu_ci[0]) / (2 * T19)


def test_stiction_drag_behaves_as_documented():
    """The generator: the speeds and forces of the real recordings, in contact throughout, Coulomb friction, noise
    growing with the force with Student t5 tails, and spikes where the truth says.

    Tolerances: the noise sd of 20 000 samples estimated to ~1 % x sqrt(kurtosis 9 - 1) / sqrt(2) = 2 %; the share of
    t5 samples beyond 3 sd (1.3 %, 260 expected) to a Poisson 4 sd.
    """
    rec = stiction_drag(mu=MU, seed=4, drift=0.0)
    a, truth = rec.arrays, rec.truth
    assert 130.0 <= a["speed"].min() and a["speed"].max() <= 320.0
    assert a["normal_force"].min() > 0.1 and a["normal_force"].max() < 4.4      # in contact throughout
    spike = truth["spike_mask"]
    assert len(truth["spike_starts"]) == 20 and 0.02 * 20 * 1000 <= spike.sum() <= 0.08 * 20 * 1000
    runs = np.diff(np.concatenate([[0], spike.astype(int), [0]]))
    assert np.sum(runs == 1) == 20                                              # 20 separate spikes
    noise = a["tangential_force"] - MU * a["normal_force"]                      # + MU x the normal force's sensor noise
    sd = truth["noise_sd"]
    z = noise[~spike] / sd[~spike]
    assert np.std(z) == pytest.approx(1.0, rel=0.06)   # 3 x 2 %; the normal force's 0.01 N adds 0.4 x 0.01 N
    heavy, light = sd > np.quantile(sd, 0.8), sd < np.quantile(sd, 0.2)
    assert np.std(noise[heavy & ~spike]) > 4 * np.std(noise[light & ~spike])   # sd 0.04 N x force: 5-10 x across the range
    expected = 2 * stats.t.sf(3 * np.sqrt(5 / 3), 5) * z.size
    assert np.sum(np.abs(z) > 3) == pytest.approx(expected, abs=4 * np.sqrt(expected))
    assert np.all(a["tangential_force"][spike] > 1.5 * MU * a["normal_force"][spike] - 6 * sd[spike])   # 2-3 x kinetic


def test_no_spike_recording_is_not_rejected_as_outliers():
    """The case found last session: a generated recording without stiction spikes (friction noise proportional to
    the force, slow, Gaussian) had 12-13 % of its samples rejected, all at heavy contact.

    Its noise is a 1-Hz Gaussian drift; measured on the drift alone (300 records of flowtex.datasets.realistic.wander,
    each standardised by its own MAD), no record had a sample past the rule (rule of three: P < 1 %, 95 %
    confidence); 0.4 % leaves room for the fitted scale function's error.
    """
    rec = textured_exploration(seed=0)
    n, t = rec.arrays["normal_force"], rec.arrays["tangential_force"]
    fit = fit_friction(n, t)
    assert fit.noise == "force"
    assert fit.rejected / fit.in_contact <= 0.004
    one_scale = fit_friction(n, t, noise="constant")   # the old fit: one residual scale for every force
    assert one_scale.rejected / one_scale.in_contact > 0.05
    assert fit.noise_exponent == pytest.approx(1.0, abs=0.5)   # the noise is proportional to the force


@pytest.mark.parametrize("dof", [5.0, np.inf])
def test_rejected_share_is_the_rules_false_rejection_rate(dof):
    """No spike, no drift, white noise sqrt(0.01^2 + (0.04 N)^2) N, Student t5 or Gaussian, over 3 recordings.

    Expected: false_rejection_rate(dof) x 60 000 samples (236 for t5, 0.17 for Gaussian). Tolerance: 4 binomial
    standard deviations, plus the scale's own error: the MAD of 20 000 t5 samples has a relative SE of ~1 % and
    the t5 tail falls as threshold^-5, so 4 of those move the share by 20 %. Measured 10-30 % below the
    expectation: the normal force's 0.01 N Gaussian sensor noise (x mu) joins the t5 noise and thins the tails
    at light contact. The one-scale fit rejects 5-7 %.
    """
    rejected = total = 0
    for seed in range(3):
        rec = stiction_drag(seed=seed, tail_dof=dof, drift=0.0, spikes=0)
        fit = fit_friction(rec.arrays["normal_force"], rec.arrays["tangential_force"])
        rejected += fit.rejected
        total += fit.in_contact
        if seed == 0 and np.isfinite(dof):
            old = fit_friction(rec.arrays["normal_force"], rec.arrays["tangential_force"], noise="constant")
            assert old.rejected / old.in_contact > 0.04
    expected = false_rejection_rate(dof) * total
    if np.isfinite(dof):
        assert rejected == pytest.approx(expected, abs=4 * np.sqrt(expected) + 0.2 * expected)
    else:
        assert rejected <= 2   # Poisson(0.17): P(>= 3) = 7e-4


def test_planted_stiction_is_found():
    """20 stiction spikes of 20-80 ms at 2-3 x the kinetic force, t5 noise, 5 % drift, 3 recordings.

    Recall: a spike stands >= (2 - 1) mu N / s(N) >= 7.7 noise sd out (at 0.3 N), so it is missed only where the
    noise is below -3 sd (t5: P = 0.4 %): recall >= 0.99. Precision: the clean samples rejected are at most the t5
    rate (drift is Gaussian and only thins the tails of the sum) plus 4 binomial sd, over ~19 000 clean samples.
    """
    for seed in range(3):
        rec, fit = _drag_fit(seed)
        n, t = rec.arrays["normal_force"], rec.arrays["tangential_force"]
        spike = rec.truth["spike_mask"]
        rejected = irls_line_hetero(n, t).line.weights == 0.0
        assert fit.rejected == int(rejected.sum())
        assert np.sum(rejected & spike) / spike.sum() >= 0.99
        clean = int((~spike).sum())
        bound = false_rejection_rate(5.0) * clean
        assert np.sum(rejected & ~spike) <= bound + 4 * np.sqrt(bound)
        assert fit.rejected_stretches >= 20 and fit.longest_stretch_samples <= 80


def test_mu_and_its_interval_over_seeds():
    """mu within 4 standard errors of the truth, and the 95 % interval covering it at about its rate.

    The SE is the fit's own; it is checked against the SE of statsmodels' WLS with the true weights on the clean
    samples without drift (bisquare at t5 is at least as efficient: 0.75-1.3 of it, the batch-means SE scattering
    by ~23 %). Coverage: 8 recordings with drift; at the nominal 95 % P(>= 6 of 8) = 99.4 %; at the 88 % batch
    means held under 1-s drift (tests/dsp/test_robust_intervals.py) 92 %.
    """
    sm = pytest.importorskip("statsmodels.api")
    held = 0
    for seed in range(8):
        _rec, fit = _drag_fit(seed)
        assert abs(fit.mu - MU) <= 4 * _se(fit)
        held += fit.mu_ci[0] <= MU <= fit.mu_ci[1]
    assert held >= 6
    for seed in range(2):
        rec = stiction_drag(mu=MU, seed=seed, drift=0.0)
        n, t = rec.arrays["normal_force"], rec.arrays["tangential_force"]
        fit = fit_friction(n, t)
        keep = ~rec.truth["spike_mask"]
        wls = sm.WLS(t[keep], n[keep], weights=rec.truth["noise_sd"][keep] ** -2).fit()
        assert 0.75 <= _se(fit) / wls.bse[0] <= 1.3
        assert abs(fit.mu - MU) <= 4 * wls.bse[0]


def test_cli_reports_the_noise_model_and_rejections(tmp_path, capsys):
    path = stiction_drag(seed=2).save(tmp_path / "drag.npz")
    out = tmp_path / "mu.json"
    assert main(["fit", "friction", str(path), "--force", "normal_force", "--friction-force", "tangential_force",
                 "-o", str(out)]) == 0
    text = capsys.readouterr().out
    doc = json.loads(out.read_text())
    assert "residual scale grows with the normal force as N^" in text
    assert f"rejected {doc['rejected']} samples" in text and "stretches" in text
    assert "0.0003 % of samples there if Gaussian" in text and "0.39 % if Student t" in text
    assert doc["noise"] == "force" and doc["rejected_share"] == pytest.approx(doc["rejected"] / doc["in_contact"])
    assert doc["scale_n"][0] < doc["residual_scale_n"] == doc["scale_n"][1] < doc["scale_n"][2]
    assert main(["fit", "friction", str(path), "--force", "normal_force", "--friction-force", "tangential_force",
                 "--noise", "constant", "-o", str(out)]) == 0
    assert "one residual scale" in capsys.readouterr().out
    assert json.loads(out.read_text())["noise"] == "constant"
