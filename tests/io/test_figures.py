"""flowtex.io.figures.save_png writes what matplotlib's own savefig writes, pixel for pixel: it runs a figure's
layout engine once and draws once, where savefig would lay out in a pass without output and then draw."""

from __future__ import annotations

import numpy as np
import pytest

from flowtex.datasets.realistic import human_exploration
from flowtex.fit.compare import compare_signals
from flowtex.fit.texture import TextureOptions, fit_texture

RATE = 1000.0


@pytest.fixture(scope="module")
def plt():
    pytest.importorskip("matplotlib")
    from flowtex.io.figures import agg_pyplot

    return agg_pyplot("matplotlib")


def _figures(plt):
    """(name, a function making the figure) for the report figures with a layout engine: many panels, a colorbar."""
    from flowtex.fit.compare_report import FIGURES
    from flowtex.fit.report import near_duplicates, plane_figure, spectra_figure

    a = human_exploration(6.0, RATE, seed=2).arrays  # 11 pieces: a figure of many panels, drawn at half the cost of 12 s
    fit = fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2)))
    rng = np.random.default_rng(3)
    x = rng.standard_normal(8000)
    comparison = compare_signals(x, [x + 0.3 * rng.standard_normal(x.size)], RATE)
    yield "spectra", lambda: spectra_figure(fit, plt)
    yield "plane", lambda: plane_figure(fit, plt, near_duplicates(fit.model_set))
    for name, figure in FIGURES.items():
        yield name, lambda figure=figure: figure(comparison, plt)


def test_save_png_is_savefigs_picture(plt, tmp_path):
    from matplotlib.image import imread

    from flowtex.io.figures import save_png

    for name, make in _figures(plt):
        fig = make()
        assert fig.get_layout_engine() is not None, name  # the case save_png changes
        fig.savefig(tmp_path / "reference.png", dpi=100, format="png")  # matplotlib's two passes
        plt.close(fig)
        save_png(make(), tmp_path / "ours.png")
        reference, ours = imread(tmp_path / "reference.png"), imread(tmp_path / "ours.png")
        assert ours.shape == reference.shape, name
        assert np.array_equal(ours, reference), f"{name}: {np.mean(ours != reference):.2%} of the values differ"
