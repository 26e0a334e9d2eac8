"""flowtex plot: units from metadata or names, a PNG written for a small output file."""

from __future__ import annotations

import json

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.plotting import signal_units


def test_units_from_metadata_beat_guesses():
    arrays = {"vibration": np.zeros(3), "friction_force": np.zeros((3, 3)), "odd": np.zeros(3), "rate": np.array(1000.0),
              "units": np.array(json.dumps({"odd": "m/s^2"})), "vibration__unit": np.array("g")}
    assert signal_units(arrays) == {"vibration": "g", "friction_force": "N", "odd": "m/s^2"}


def test_plot_writes_a_png(tmp_path):
    rng = np.random.default_rng(0)
    n = 2000
    np.savez(tmp_path / "out.npz", vibration=rng.normal(size=n) * (np.arange(n) > 500), velocity=rng.normal(size=(n, 3)),
             force=rng.normal(size=(n, 3)), rate=np.array(1000.0))
    assert main(["plot", str(tmp_path / "out.npz"), "-o", str(tmp_path / "p.png")]) == 0
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert main(["plot", str(tmp_path / "out.npz"), "--signals", "nothing"]) == 1


def test_plot_uses_the_units_a_recording_stores(tmp_path, monkeypatch):
    """A friction force stored in N is labelled [N], whatever its name (it was labelled [-]: load_recording moves the
    stored units out of the arrays)."""
    import flowtex.plotting as plotting
    from flowtex.io.recordings import save_recording

    seen = {}
    monkeypatch.setattr(plotting, "plot_signals", lambda signals, units, *a, **k: seen.update(units))
    n = 500
    for suffix in (".npz", ".csv", ".h5"):
        path = tmp_path / f"rec{suffix}"
        save_recording(path, {"friction": np.zeros(n), "accel": np.zeros(n), "tool": np.zeros(n)}, rate=1000.0,
                       units={"friction": "N", "accel": "g", "tool": "mm/s"})
        seen.clear()
        plotting.plot_recording(path, None, tmp_path / "p.png")
        assert seen == {"friction": "N", "accel": "g", "tool": "mm/s"}, suffix


def _signals(n_force: int, rng):
    """A run's outputs: ``n_force`` 3-axis forces, a vibration (a spectrogram row), a velocity (a force-speed panel)."""
    n = 3000
    sig = {f"force{i}" if i else "force": rng.normal(size=(n, 3)) for i in range(n_force)}
    sig |= {"vibration": rng.normal(size=n), "velocity": rng.normal(size=(n, 3)) * 100}
    return sig, {k: "N" if k.startswith("force") else "m/s^2" if k == "vibration" else "mm/s" for k in sig}


@pytest.mark.parametrize("n_force", [1, 4, 12])
def test_plot_layout_title_legends_and_fonts_on_short_and_tall_figures(n_force):
    """The title stays clear of the first panel on a tall figure (12 forces, 16 rows: it overlapped before), legends
    cover no data, every text is inside the figure and readable; the time panels share one time axis, 0 to the end."""
    pytest.importorskip("matplotlib")
    from flowtex.io.figures import agg_pyplot
    from flowtex.plotting import signals_figure
    from tests.figure_layout import layout_problems

    plt = agg_pyplot("matplotlib")
    sig, units = _signals(n_force, np.random.default_rng(1))
    fig = signals_figure(sig, units, 1000.0, title="run.npz")
    try:
        assert layout_problems(fig) == []
        r = fig.canvas.get_renderer()
        time_axes = [ax for ax in fig.axes if ax.get_xlabel() == "time (s)"]
        assert len(time_axes) == len(sig) + 1  # every signal and the vibration's spectrogram
        extents = {(round(ax.get_window_extent(r).x0), round(ax.get_window_extent(r).x1)) for ax in time_axes}
        assert len(extents) == 1  # same left and right edges: times line up across panels
        assert all(ax.get_xlim() == (0.0, 3.0) for ax in time_axes)
    finally:
        plt.close(fig)


def test_spectrogram_spans_the_whole_recording_and_keeps_its_power():
    """The picture stopped up to a segment short of the end (1.81 s of a 2 s run was drawn), as if nothing had been
    recorded there; its PSD integrates to the signal's variance (Parseval; white noise, 20 000 values)."""
    pytest.importorskip("matplotlib")
    from matplotlib.collections import QuadMesh

    from flowtex.dsp.spectral import spectrogram_psd
    from flowtex.io.figures import agg_pyplot
    from flowtex.plotting import signals_figure

    rng = np.random.default_rng(3)
    x = 2.0 * rng.standard_normal(20000)
    f, t, s = spectrogram_psd(x, 1000.0)
    assert t[0] == 0.0 and t[-1] >= 19.9 and f[-1] == 500.0
    power = np.sum(np.mean(s, axis=1)) * (f[1] - f[0])
    assert power == pytest.approx(np.var(x), rel=0.03)  # ~2500 segments: the estimate scatters by well under 1 %

    plt = agg_pyplot("matplotlib")
    fig = signals_figure({"vibration": x[:2000]}, {"vibration": "m/s^2"}, 1000.0)
    try:
        mesh = next(c for ax in fig.axes for c in ax.collections if isinstance(c, QuadMesh))
        xs = mesh.get_coordinates()[..., 0]
        assert xs.min() <= 0.0 and xs.max() >= 2.0
    finally:
        plt.close(fig)


def test_force_speed_panel_for_a_speed_in_any_stated_unit():
    """A speed stated in m/s got no force-speed panel (only exactly "mm/s" did); it gets one labelled in m/s."""
    pytest.importorskip("matplotlib")
    from flowtex.io.figures import agg_pyplot
    from flowtex.io.recording_rules import is_speed_unit
    from flowtex.plotting import signals_figure

    assert [is_speed_unit(u) for u in ("m/s", "m*s^-1", "m s^-1", "cm/s", "mm/s", "m/s^2", "mm", "N")] == [True] * 5 + [False] * 3
    plt = agg_pyplot("matplotlib")
    fig = signals_figure({"speed": np.linspace(0, 0.2, 50), "force": np.ones((50, 3))}, {"speed": "m/s", "force": "N"}, 1000.0)
    try:  # built, not drawn
        assert [ax.get_xlabel() for ax in fig.axes if ax.get_xlabel() != "time (s)"] == ["|speed| (m/s)"]
    finally:
        plt.close(fig)


def test_a_vibration_in_g_gets_its_spectrogram_and_a_force_in_mn_its_panel():
    """Only exactly "m/s^2" got a spectrogram and only exactly "N" a force-speed panel: a vibration in g and a force in
    mN got neither. Each is drawn in its stated unit (built, not drawn)."""
    pytest.importorskip("matplotlib")
    from matplotlib.collections import QuadMesh

    from flowtex.io.figures import agg_pyplot
    from flowtex.io.recording_rules import is_unit_of
    from flowtex.plotting import signals_figure

    assert [is_unit_of(u, "m/s^2") for u in ("g", "mm/s^2", "m/s/s", "m s^-2", "m/s", "N")] == [True] * 4 + [False] * 2
    assert [is_unit_of(u, "N") for u in ("N", "mN", "kN", "kg", "")] == [True] * 3 + [False] * 2
    plt = agg_pyplot("matplotlib")
    n = 2000
    fig = signals_figure({"accel": np.sin(np.arange(n)), "speed": np.linspace(50, 200, n), "friction": np.full(n, 300.0)},
                         {"accel": "g", "speed": "mm/s", "friction": "mN"}, 1000.0)
    try:
        spectrograms = [ax for ax in fig.axes if "frequency (Hz)" in ax.get_ylabel()]
        assert len(spectrograms) == 1 and any(isinstance(c, QuadMesh) for c in spectrograms[0].collections)
        assert any("(g)^2/Hz" in ax.get_ylabel() for ax in fig.axes)  # its colorbar, in the stated unit
        assert any(ax.get_xlabel() == "|speed| (mm/s)" and ax.get_ylabel() == "|friction| (mN)" for ax in fig.axes)
    finally:
        plt.close(fig)


def test_values_beyond_what_a_plot_can_draw_are_left_out_and_named(tmp_path, capsys):
    """A signal reaching 1.7e308 was an internal error (matplotlib's tick arithmetic overflowed); a vibration of 1e200
    drew a blank spectrogram (its PSD overflowed) without a word. Now both are drawn without those values, and said."""
    pytest.importorskip("matplotlib")
    n = 400
    big = np.where(np.arange(n) % 2, 1.7e308, -1.7e308)
    np.savez(tmp_path / "out.npz", x=big * (np.arange(n) >= 100), vibration=np.full(n, 1e200) * (np.arange(n) >= 300),
             rate=np.array(1000.0))
    assert main(["plot", str(tmp_path / "out.npz"), "-o", str(tmp_path / "p.png")]) == 0
    err = capsys.readouterr().err.splitlines()
    assert err[:2] == [f"warning: {tmp_path / 'out.npz'}: signal 'x': 300 sample(s) beyond +-1e+150 (or infinite) are not drawn, "
                   "the first at 0.1 s (sample 100)",
                   f"warning: {tmp_path / 'out.npz'}: signal 'vibration': 100 sample(s) beyond +-1e+150 (or infinite) are not "
                   "drawn, the first at 0.3 s (sample 300)"]
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_file_name_or_unit_that_is_not_utf8_is_drawn_escaped(tmp_path, capsys):
    """A file name with bytes that are not UTF-8 (Python holds them as lone surrogates) or a JSON unit "\\udcff" was an
    internal error: matplotlib's font code refused the title or label."""
    pytest.importorskip("matplotlib")
    name = tmp_path / "bad\udcffname.npz"  # the name b"bad\xffname.npz" as os.fsdecode gives it
    np.savez(name, x=np.zeros(200), rate=np.array(1000.0), units=np.array(json.dumps({"x": "m\udcff"})))
    assert main(["plot", str(name), "-o", str(tmp_path / "p.png")]) == 0, capsys.readouterr().err
    assert (tmp_path / "p.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_spectrogram_of_a_3_axis_vibration_with_gravity_shows_its_frequency():
    """A 100 Hz vibration along (1, 1, 1)/sqrt(3) on an accelerometer reading gravity on z: the spectrogram drew the
    PSD of the magnitude |a| (a rectified signal: its power at 0 and 200 Hz, 100 Hz 56 dB down) and let the 0 Hz of
    the offset set the colour range. Now the axes' PSDs are summed with each segment's mean removed: 100 Hz is the
    brightest row, and the picture's power is the vibration's (Parseval)."""
    pytest.importorskip("matplotlib")
    from matplotlib.collections import QuadMesh

    from flowtex.dsp.spectral import spectrogram_psd
    from flowtex.io.figures import agg_pyplot
    from flowtex.plotting import signals_figure

    n, rate = 4000, 1000.0
    vib = 0.05 * np.sin(2 * np.pi * 100.0 * np.arange(n) / rate)
    accel = np.outer(vib, np.ones(3) / np.sqrt(3.0)) + np.array([0.0, 0.0, 9.81])
    f, _, s = spectrogram_psd(accel, rate)
    mean = s.mean(axis=1)
    assert f[np.argmax(mean)] == pytest.approx(100.0, abs=f[1])
    assert np.sum(mean) * f[1] == pytest.approx(np.var(vib), rel=0.05)
    plt = agg_pyplot("matplotlib")
    fig = signals_figure({"accel": accel}, {"accel": "m/s^2"}, rate)
    try:
        ax = next(ax for ax in fig.axes if "frequency (Hz)" in ax.get_ylabel())
        assert "sum of 3 axes" in ax.get_ylabel()
        db = next(c for c in ax.collections if isinstance(c, QuadMesh)).get_array().reshape(len(f), -1)
        assert f[np.argmax(db.mean(axis=1))] == pytest.approx(100.0, abs=f[1])
    finally:
        plt.close(fig)


def test_force_speed_panel_prefers_the_normal_force():
    """A recording listing its tangential force before its normal force got a trace of the tangential force against
    the speed, labelled as the force-speed trace: the normal force is the operating point's."""
    pytest.importorskip("matplotlib")
    from flowtex.io.figures import agg_pyplot
    from flowtex.plotting import signals_figure

    plt = agg_pyplot("matplotlib")
    n = 500
    fig = signals_figure({"tangential_force": np.ones(n), "normal_force": np.full(n, 2.0), "speed": np.linspace(50, 200, n)},
                         {"tangential_force": "N", "normal_force": "N", "speed": "mm/s"}, 1000.0)
    try:  # built, not drawn
        assert [ax.get_ylabel() for ax in fig.axes if ax.get_xlabel() == "|speed| (mm/s)"] == ["|normal_force| (N)"]
    finally:
        plt.close(fig)
