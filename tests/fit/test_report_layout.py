"""The figures of ``fit texture --report`` and ``compare --report`` as a reader sees them: titles clear of the panels,
legends clear of the data, text inside the figure and readable (tests/figure_layout.py), axes labelled with units,
and the printed summary saying which number is the render's and which the recording's."""

from __future__ import annotations

import re

import numpy as np
import pytest

from flowtex.datasets.realistic import human_exploration
from flowtex.fit.compare import compare_signals, summary_lines
from flowtex.fit.texture import TextureOptions, fit_texture
from tests.figure_layout import layout_problems

RATE = 1000.0


@pytest.fixture(scope="module")
def plt():
    pytest.importorskip("matplotlib")
    from flowtex.io.figures import agg_pyplot

    return agg_pyplot("matplotlib")


@pytest.fixture(scope="module")
def comparison():
    """A recording of slowly changing loudness and a render of it with its own noise and a 1.5x louder band."""
    rng = np.random.default_rng(3)
    n = int(16 * RATE)
    x = rng.standard_normal(n) * np.repeat(1.0 + 0.5 * np.sin(np.arange(16)), 1000)
    renders = [x + 0.3 * rng.standard_normal(n) for _ in range(2)]
    return compare_signals(x, renders, RATE)


def _units_on_axes(fig) -> list[str]:
    """Axis labels without a unit in parentheses (every labelled axis of a report plot has one)."""
    labels = [a.get_xlabel() for a in fig.axes] + [a.get_ylabel() for a in fig.axes]
    labels += [t.get_text() for t in fig.texts if t not in (getattr(fig, "_suptitle", None),)]
    return [s for s in labels if s and not re.search(r"\(.+\)", s)]


def test_compare_report_figures_are_laid_out_for_a_paper(plt, comparison):
    from flowtex.fit.compare_report import FIGURES

    assert sorted(FIGURES) == ["loudness.png", "octaves.png", "spectrum.png", "windows.png"]
    for name, figure in FIGURES.items():
        fig = figure(comparison, plt)
        try:
            assert layout_problems(fig) == [], name
            assert _units_on_axes(fig) == [], name
            assert all(ax.get_xlabel() not in ("s", "Hz") for ax in fig.axes), name  # a bare unit is not a label
        finally:
            plt.close(fig)


def test_compare_summary_says_which_rms_and_centroid_is_the_render(comparison):
    """It printed 'RMS a vs b' and 'centroid a vs b Hz' with the render first, while the report's table puts the
    recording first: the reader could not tell which was which."""
    c = comparison
    text = "\n".join(summary_lines(c))
    assert f"RMS {c.rendered_rms:.3g} rendered, {c.recorded_rms:.3g} recorded (m/s^2)" in text
    assert f"centroid {c.rendered_centroid_hz:.0f} Hz rendered, {c.centroid_hz:.0f} Hz recorded" in text
    assert " vs " not in text


@pytest.fixture(scope="module")
def fit(tmp_path_factory):
    """11 pieces: three rows of four panels, one panel off (the 12-s recording's 19 pieces gave five such rows at
    twice the drawing cost); model numbers of two digits; models moved off their pieces by pooling."""
    rec = human_exploration(6.0, RATE, seed=2)
    a = rec.arrays
    return fit_texture(a["accel"], a["speed"], a["normal_force"], RATE, TextureOptions(order=(4, 2)))


def test_fit_report_figures_are_laid_out_for_a_paper(plt, fit):
    from flowtex.fit.report import near_duplicates, plane_figure, spectra_figure

    assert len(fit.pieces) >= 5  # several rows of panels
    for name, fig in (("spectra", spectra_figure(fit, plt)), ("plane", plane_figure(fit, plt, near_duplicates(fit.model_set)))):
        try:
            assert layout_problems(fig) == [], name
            assert _units_on_axes(fig) == [], name
        finally:
            plt.close(fig)


def test_fit_table_names_the_units_and_its_columns_line_up(fit):
    """The header said 'speed' and 'force' without units, which a table copied into a paper needs."""
    from flowtex.fit.report import table_lines

    header, *rows = table_lines(fit)
    assert header.split() == ["model", "speed", "mm/s", "force", "N", "samples", "order", "GFC", "LSD", "dB", "LSD", "floor",
                              "power", "dB"]
    ends = [m.end() for m in re.finditer(r"(model|speed mm/s|force N|samples|order|GFC|LSD dB|LSD floor|power dB)", header)]
    for row in rows:
        assert [m.end() for m in re.finditer(r"\S+", row)] == ends  # each value ends under its heading


def test_fit_table_gives_each_models_power_over_its_piece_in_db(fit):
    """The column read "power err" in percent of power: a pooled model 11.6 dB louder than its quiet piece printed as
    +1333.80 %. It is now the model's output power over its piece's variance in dB, the unit compare and the paper use.

    Reference, independent of the fit's closed form: the model's PSD integrated over 0..rate/2 on a fine grid (the
    trapezoid's error on these smooth order-(4, 2) spectra is far below the table's 0.005 dB rounding), and the
    piece's own variance. Pooling (the default) moves models off their pieces, so some rows differ from 0 dB."""
    from flowtex.fit.report import table_lines

    freqs = np.linspace(0.0, RATE / 2, 200_001)
    rows = {int(line.split()[0]): float(line.split()[-1]) for line in table_lines(fit)[1:]}
    moved = 0
    for pc in fit.pieces:
        f = pc.fit
        model_power = np.trapezoid(f.psd(freqs, RATE), freqs)
        assert rows[pc.model] == pytest.approx(10 * np.log10(model_power / f.data_variance), abs=0.0051)
        moved += abs(rows[pc.model]) >= 0.01
    assert moved > 0


def test_plane_labels_of_near_duplicate_models_stay_readable(plt, fit):
    """Two models closer than 2 % were circled as near-duplicates, and their numbers were drawn at the same offset
    from nearly the same point, one over the other: the figure pointed at them and hid which they were."""
    import copy

    from flowtex.fit.report import near_duplicates, plane_figure

    f = copy.deepcopy(fit)
    ms = f.model_set
    a, b = sorted(f.pieces, key=lambda pc: pc.model)[:2]
    for pc in (b,):  # model b moved to 0.5 % of the ranges from model a
        pc.speed, pc.force = a.speed + 0.005 * ms.max_speed, a.force + 0.005 * ms.max_force
        ms.speeds[pc.model], ms.forces[pc.model] = pc.speed, pc.force
    dups = near_duplicates(ms)
    assert (a.model, b.model) in dups
    fig = plane_figure(f, plt, dups)
    try:
        assert layout_problems(fig) == []
    finally:
        plt.close(fig)


def test_held_out_table_names_the_window_of_its_rms_correlation():
    """fit texture's held-out comparisons use 0.5-s windows (flowtex.fit.crossval.CV_WINDOW_S), the printout said so and
    the report's table only 'window-RMS correlation', which a reader takes for compare's 1-s figure."""
    from flowtex.fit.compare import CompareOptions
    from flowtex.fit.crossval import CV_WINDOW_S, holdout_doc
    from flowtex.fit.report import HeldOut, held_out_lines

    rng = np.random.default_rng(4)
    x = rng.standard_normal(int(12 * RATE)) * np.repeat(1.0 + 0.5 * np.sin(np.arange(24)), 500)
    c = compare_signals(x, [x + 0.2 * rng.standard_normal(x.size)], RATE, CompareOptions(window_s=CV_WINDOW_S))
    lines = held_out_lines(HeldOut("held out: test", [c], holdout_doc("blocks", "fraction", 0.3, [c])))
    header = next(line for line in lines if line.startswith("| fold"))
    assert f"{CV_WINDOW_S:g}-s window-RMS correlation" in header


def test_compare_report_table_states_units_and_the_spectrum_title_the_power_ratios_band(plt, comparison):
    """The window table's RMS columns had no unit and read 2.3 under 3.06 (three significant digits, trailing zeros
    dropped); the spectrum's title put the LSD's band after the power ratio, which is measured from 12 Hz to the
    Nyquist frequency (for a set resampled up, 12-400 Hz was read as the power ratio's band too)."""
    from dataclasses import replace

    from flowtex.fit.compare_report import spectrum_figure, window_table

    c = replace(comparison, windows=[dict(comparison.windows[0], recorded_rms=2.3, rendered_rms=123.4)],
                band_hz=[12.0, 400.0])
    header, _, row = window_table(c)
    assert "recorded RMS m/s^2" in header and "rendered RMS m/s^2" in header
    assert "| 2.30 | 123 |" in row
    fig = spectrum_figure(c, plt)
    try:
        assert fig.axes[0].get_title().startswith(f"power ratio {c.power_ratio_db:+.2f} dB (> 12 Hz), LSD")
    finally:
        plt.close(fig)


def test_report_of_a_set_written_at_another_rate_says_so(fit, tmp_path, monkeypatch):
    """fit texture --render-rate 2000 --report DIR: the report gave the fitted set's '... N models, T triangles' and
    orders at 1 kHz and said nothing of the file written (resampled to 2 kHz, other orders, models added between the
    fitted ones), so its numbers were read as the file's. It now states what was written."""
    from types import SimpleNamespace

    import flowtex.fit.report as report
    import flowtex.fit.texture_job as texture_job
    from flowtex.cli import main

    ms = fit.model_set
    written = SimpleNamespace(sample_rate=2000.0, ar_order=ms.ar_order + 2, ma_order=ms.ma_order + 2,
                              num_models=ms.num_models, triangles=ms.triangles)  # what the report reads of it
    monkeypatch.setattr(texture_job, "fit_recording", lambda path, job: fit)
    monkeypatch.setattr(texture_job, "write_outputs", lambda *a, **k: written)
    monkeypatch.setattr(report, "agg_pyplot", lambda hint: None)  # no figures: the text is the point
    monkeypatch.setattr(report, "print_table", lambda f: None)
    rec = tmp_path / "rec.npz"
    rec.write_bytes(b"")
    argv = ["fit", "texture", str(rec), "--speed", "speed", "--render-rate", "2000", "-o", str(tmp_path / "s.json"),
            "--report", str(tmp_path / "rep")]
    assert main(argv) == 0
    text = (tmp_path / "rep" / "report.md").read_text()
    assert (f"Written at 2000 Hz (--render-rate): resampled from 1000 Hz, orders {ms.ar_order},{ms.ma_order} -> "
            f"{ms.ar_order + 2},{ms.ma_order + 2}, {ms.num_models} models (0 added") in text
    assert report.written_lines(fit, ms) == [] and report.written_lines(fit, None) == []


def test_plane_tells_the_recorded_path_from_the_triangulation(plt, fit):
    """The recorded path was drawn in light grey under the triangulation's grey edges, the two told apart by shade
    alone: on paper the path could not be followed. It now has a colour of its own, and both are in the legend."""
    from matplotlib.colors import to_rgb

    from flowtex.fit.report import near_duplicates, plane_figure

    fig = plane_figure(fit, plt, near_duplicates(fit.model_set))
    try:
        ax = fig.axes[0]
        lines = {line.get_label(): line for line in ax.get_lines()}
        path, edges = lines["recorded path"], lines["triangulation"]
        r, g, b = to_rgb(path.get_color())
        assert max(r, g, b) - min(r, g, b) > 0.3  # a colour, not a grey
        assert to_rgb(path.get_color()) != to_rgb(edges.get_color())
        assert {"recorded path", "triangulation"} <= {t.get_text() for legend in fig.legends for t in legend.get_texts()}
    finally:
        plt.close(fig)


def test_fit_warns_when_the_pieces_ends_held_the_loud_bursts(fit, capsys):
    """On a recording with bursts and 6 dB of loudness wander (resonant.textured_exploration(12, seed=5,
    loudness_db=6, burst=1.5)) the segmenter put two piece boundaries at bursts, the 0.05-s trims cut them away with
    60 % of the recording's energy, and the fit rendered 2.5 dB too quiet with nothing said. The pieces' level against
    that of the pieces with their trims is now measured, and a loss of more than 1 dB is a warning."""
    from types import SimpleNamespace

    from flowtex.fit.report import edge_warning
    from flowtex.fit.texture import Piece, trimmed_level_db

    rng = np.random.default_rng(0)
    x = rng.standard_normal(3000)
    pieces = [Piece(100, 1400, 100.0, 1.0), Piece(1600, 2900, 200.0, 2.0)]
    assert abs(trimmed_level_db(x, pieces, 100)) < 0.3  # trims like the pieces
    x[1400:1500] *= 10.0  # a burst in the trim after the first piece
    level = trimmed_level_db(x, pieces, 100)
    assert level < -3.0
    assert trimmed_level_db(np.zeros(3000), pieces, 100) == 0.0
    warned = edge_warning(SimpleNamespace(edge_level_db=level, model_set=SimpleNamespace(material="m")))
    assert warned is not None and f"{-level:.1f} dB below" in warned
    assert edge_warning(SimpleNamespace(edge_level_db=-0.5, model_set=SimpleNamespace(material="m"))) is None
    # a fit measures its own pieces (the person-like recording of the fixture: no loud ends, no warning)
    assert fit.edge_level_db == trimmed_level_db(fit.signal, fit.pieces, int(round(0.05 * RATE)))
    assert edge_warning(fit) is None
