"""Held-out splits (flowtex.fit.crossval), fit texture --holdout-split/--folds/--holdout-json and the fit report."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.realistic import human_exploration
from flowtex.errors import DataError
from flowtex.fit.compare import CompareOptions, compare_signals, compare_surface, welch_length
from flowtex.fit.crossval import CV_WINDOW_S, blocks, evaluate_splits, fold_splits, holdout_split
from flowtex.fit.texture import TextureOptions, fit_texture

RATE = 1000.0


def _covered(ranges, n):
    mask = np.zeros(n, int)
    for a, b in ranges:
        mask[a:b] += 1
    return mask


def test_blocks_and_splits_partition_the_recording():
    n = 19500                                   # 19.5 s: the last block is half a second
    assert blocks(n, RATE)[-1] == (19000, 19500) and len(blocks(n, RATE)) == 20
    train, test = holdout_split(n, RATE, 0.5, "blocks")
    assert np.all(_covered(train, n) + _covered(test, n) == 1)            # every sample in exactly one part
    assert test[0] == (1000, 2000) and test[1] == (3000, 4000)             # every other second: the odd ones
    train, test = holdout_split(n, RATE, 0.25, "blocks")
    assert [a // 1000 for a, _ in test] == [3, 7, 11, 15, 19]              # every fourth second
    train, test = holdout_split(n, RATE, 0.3, "tail")
    assert train == [(0, 13650)] and test == [(13650, n)]
    folds = fold_splits(n, RATE, 3)
    assert np.all(sum(_covered(t, n) for _, t in folds) == 1)             # K folds hold out each sample once
    for train, test in folds:
        assert np.all(_covered(train, n) + _covered(test, n) == 1)
    assert [a // 1000 for a, _ in folds[1][1]] == [1, 4, 7, 10, 13, 16, 19]
    with pytest.raises(DataError, match="at least 2"):
        fold_splits(n, RATE, 1)
    with pytest.raises(DataError, match="at least 8 one-second blocks"):
        fold_splits(5000, RATE, 4)
    with pytest.raises(DataError, match="fewer than 2 s"):
        holdout_split(n, RATE, 0.05, "blocks")
    with pytest.raises(DataError, match="tail or blocks"):
        holdout_split(n, RATE, 0.5, "middle")


def test_fit_within_blocks_uses_only_those_blocks_and_splices_nothing():
    """Pieces lie inside the training blocks, and the signal is the whole recording's high-pass (no splice)."""
    rec = human_exploration(12.0, RATE, seed=3)
    a = rec.arrays
    train, _test = holdout_split(a["accel"].shape[0], RATE, 0.5, "blocks")
    fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2)), within=train)
    for p in fit.pieces:
        assert any(lo <= p.start and p.stop <= hi for lo, hi in train)
    full = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2)))
    np.testing.assert_array_equal(fit.signal, full.signal)


def test_compare_on_ranges_equals_compare_on_each_block_pooled():
    """Ranges: the PSD is the segment-weighted mean of each range's Welch PSD; a scaled copy is exact anywhere."""
    rng = np.random.default_rng(4)
    x = rng.standard_normal(14000) * np.repeat(np.linspace(0.5, 2.0, 14), 1000)
    ranges = [(1000, 2000), (3000, 4000), (5000, 6000)]
    c = compare_signals(x, [np.sqrt(2.0) * x], RATE, ranges=ranges)
    assert c.power_ratio_db == pytest.approx(10 * np.log10(2.0), abs=1e-9)
    assert c.seconds == pytest.approx(3.0) and len(c.windows) == 3
    assert [w["start_s"] for w in c.windows] == [1.0, 3.0, 5.0]
    # a render that is wrong only outside the ranges does not count
    y = x.copy()
    y[7000:] *= 10.0
    assert compare_signals(x, [y], RATE, ranges=ranges).power_ratio_db == pytest.approx(0.0, abs=1e-9)


def test_pooled_renders_each_held_out_block_by_the_surface_that_did_not_see_it():
    """The pooled comparison is every fold's held-out blocks at once: its PSDs are the folds' held-out PSDs weighted
    by their Welch segments (a block rendered by another fold's surface, or a splice, would break the identity)."""
    rec = human_exploration(12.0, RATE, seed=5)
    a = rec.arrays
    n = a["accel"].shape[0]
    splits = fold_splits(n, RATE, 2)
    cv = evaluate_splits(a["accel"], a["speed"], a["normal_force"], RATE, splits, TextureOptions(order=(4, 2)))
    opt = CompareOptions()
    seg, skip = welch_length(RATE, opt.resolution_hz), int(opt.skip_s * RATE)
    weights = [sum(1 + (b - max(lo, skip) - seg) // (seg // 2) for lo, b in test if b - max(lo, skip) >= seg)
               for _train, test in splits]
    for key in ("rendered_psd", "recorded_psd"):
        expected = sum(w * getattr(c, key) for w, c in zip(weights, cv.comparisons, strict=True)) / sum(weights)
        np.testing.assert_allclose(getattr(cv.pooled, key), expected, rtol=1e-12)
    assert cv.pooled.seconds == pytest.approx(sum(c.seconds for c in cv.comparisons))
    assert len(cv.pooled.windows) == sum(len(c.windows) for c in cv.comparisons)
    # the two folds' surfaces differ, so the pooled render is not either one's alone
    assert not np.allclose(cv.comparisons[0].rendered_psd, cv.comparisons[1].rendered_psd)
    # each fold's in-sample figure is its surface compared on its training blocks, as compare_surface computes it
    cv_opt = CompareOptions(window_s=CV_WINDOW_S)
    for fit, own, (train, _test) in zip(cv.fits, cv.in_sample, splits, strict=True):
        alone = compare_surface(fit.model_set, a["accel"], a["speed"], a["normal_force"], RATE, cv_opt, ranges=train)
        assert own.lsd_db == pytest.approx(alone.lsd_db, rel=1e-12)
        assert own.power_ratio_db == pytest.approx(alone.power_ratio_db, rel=1e-12)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    path = tmp_path_factory.mktemp("cv") / "rec.npz"
    return human_exploration(12.0, RATE, seed=2).save(path)


def test_cli_folds_writes_json_and_report(recording, tmp_path, capsys, monkeypatch):
    """The report's figures are built but not drawn: only report.md is read here (drawing them is
    tests/fit/test_fit_texture.py's end-to-end run, their pixels tests/io/test_figures.py's, their layout
    tests/fit/test_report_layout.py's)."""
    import flowtex.fit.report as report

    drawn = []

    def keep(fig, path):
        drawn.append(path.name)
        report.agg_pyplot(None).close(fig)

    monkeypatch.setattr(report, "save_png", keep)
    out, js, rep = tmp_path / "fit.json", tmp_path / "cv.json", tmp_path / "rep"
    assert main(["fit", "texture", str(recording), "--speed", "speed", "--order", "4,2", "--folds", "2", "-o", str(out),
                 "--holdout-json", str(js), "--report", str(rep)]) == 0
    printed = capsys.readouterr().out
    assert "2-fold cross-validation over interleaved 1-s blocks" in printed and "mean over 2 folds" in printed
    doc = json.loads(js.read_text())
    assert doc["split"] == "blocks" and doc["folds"] == 2 and "fraction" not in doc and len(doc["results"]) == 2
    keys = set(doc["results"][0])
    assert {"power_ratio_db", "lsd_db", "gfc", "rms_correlation", "band_hz", "octave_bands", "windows"} <= keys
    assert set(doc["mean"]) == keys and set(doc["pooled"]) == keys - {"in_sample"}
    for r in doc["results"]:  # each fold's surface on its own training blocks: the other half of the 12 s (less the skipped start)
        assert set(r["in_sample"]) == keys - {"in_sample"}
        assert r["in_sample"]["seconds"] + r["seconds"] == pytest.approx(12.0 - CompareOptions().skip_s)
    assert doc["mean"]["in_sample"]["lsd_db"] == pytest.approx(np.mean([r["in_sample"]["lsd_db"] for r in doc["results"]]))
    assert printed.count("in-sample (the same surface on its training blocks)") == 2
    assert "pooled over the folds" in printed
    for k in ("power_ratio_db", "lsd_db", "gfc"):
        assert doc["mean"][k] == pytest.approx(np.mean([r[k] for r in doc["results"]]))
    assert doc["mean"]["octave_bands"][0]["error_db"] == pytest.approx(
        np.mean([r["octave_bands"][0]["error_db"] for r in doc["results"]]))
    md = (rep / "report.md").read_text()
    if report.agg_pyplot(None) is not None:  # the plot extra installed
        assert drawn == ["spectra.png", "plane.png"] and "![spectra](spectra.png)" in md
    assert "## Held out" in md and "2-fold cross-validation" in md and "| mean |" in md and "| pooled |" in md
    # the set written is the fit of the whole recording, its models numbered as in the report
    ms = json.loads(out.read_text())
    assert ms["metadata"]["pieces"] >= 1


def test_cli_holdout_blocks_and_option_errors(recording, tmp_path, capsys):
    out, js = tmp_path / "fit.json", tmp_path / "h.json"
    assert main(["fit", "texture", str(recording), "--speed", "speed", "--order", "4,2", "--holdout", "0.5",
                 "--holdout-split", "blocks", "-o", str(out), "--holdout-json", str(js)]) == 0
    assert "held out: 0.5 of the recording as interleaved 1-s blocks" in capsys.readouterr().out
    doc = json.loads(js.read_text())
    assert doc["split"] == "blocks" and doc["fraction"] == 0.5 and len(doc["results"]) == 1 and doc["pooled"] is None
    assert doc["results"][0]["seconds"] == pytest.approx(6.0 - 0.0)           # seconds 1, 3, 5, 7, 9, 11
    for bad, msg in ((["--folds", "2", "--holdout", "0.3"], "not both"), (["--holdout-json", str(js)], "--holdout-json"),
                     (["--holdout-split", "blocks"], "--holdout-split"), (["--folds", "1"], "--folds")):
        assert main(["fit", "texture", str(recording), "--speed", "speed", "-o", str(out), *bad]) in (1, 2)
        assert msg in capsys.readouterr().err


def test_report_numbers_models_as_the_set_and_labels_its_plots(recording, tmp_path, monkeypatch):
    """Model numbers in the table and the panels are the set's indices; the panels have a legend, and their LSD and
    GFC; the plane plot shows the recorded path and circles near-duplicate models."""
    import flowtex.fit.report as report
    from flowtex.fit.texture import Piece, assemble_set
    from flowtex.io.modelset import load_model_set, save_model_set
    from flowtex.io.recordings import load_recording

    pytest.importorskip("matplotlib")
    figs = {}
    monkeypatch.setattr(report, "save_png", lambda fig, path: figs.__setitem__(path.name, fig))
    a = load_recording(recording).arrays
    fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2)))
    # a near-duplicate of model 0: a piece 1 % of the range away
    first = min(fit.pieces, key=lambda p: p.model)
    twin = Piece(first.start, first.stop, first.speed * 1.01, first.force * 1.005, first.fit, first.lsd_db)
    fit.pieces.append(twin)
    fit.model_set = assemble_set(fit.pieces, RATE, "twin")
    ms = load_model_set(save_model_set(fit.model_set, tmp_path / "set.json"))
    md = report.write_report(fit, tmp_path / "rep").read_text()
    rows = [line.split() for line in md.splitlines() if line[:5].strip().isdigit()]
    assert len(rows) == len(fit.pieces)
    for row in rows:
        m, speed, force = int(row[0]), float(row[1]), float(row[2])
        assert ms.speeds[m] == pytest.approx(speed, abs=0.05) and ms.forces[m] == pytest.approx(force, abs=0.005)
    assert report.near_duplicates(ms) == [(first.model, twin.model)] and "Near-duplicate models" in md
    spectra = figs["spectra.png"]
    panels = [ax for ax in spectra.axes if ax.axison]
    assert len(panels) == len(fit.pieces)
    assert [t.get_text() for t in spectra.legends[0].get_texts()] == ["data (the piece's Welch PSD)", "model"]
    for ax, pc in zip(panels, sorted(fit.pieces, key=lambda p: (p.model, -p.samples)), strict=True):
        assert ax.get_title().startswith(f"model {pc.model}:")
        assert f"LSD {pc.lsd_db:.2f} dB, GFC {pc.fit.gfc:.3f}" in ax.get_title()  # in the title: nothing over the curves
        assert ax.title.get_fontsize() >= report.FONT
    labels = [t.get_text() for t in figs["plane.png"].legends[0].get_texts()]
    assert "recorded path" in labels and any(lab.startswith("near-duplicate") for lab in labels)


def test_holdout_mean_keeps_the_folds_shared_counts_as_integers():
    """The mean row's "seeds" read 4.0 where every fold's read 4; averaged figures stay floats."""
    from flowtex.fit.crossval import holdout_doc

    rng = np.random.default_rng(4)
    x = rng.standard_normal(12000)
    folds = [compare_signals(x, [x * s, x * s], RATE) for s in (1.0, 1.5)]
    doc = json.loads(json.dumps(holdout_doc("blocks", "folds", 2, folds)))
    assert [r["seeds"] for r in doc["results"]] == [2, 2] and doc["mean"]["seeds"] == 2
    assert isinstance(doc["mean"]["seeds"], int) and isinstance(doc["mean"]["seconds"], float)
    assert doc["mean"]["power_ratio_db"] == pytest.approx(np.mean([r["power_ratio_db"] for r in doc["results"]]))
