"""``flowtex plot OUT.npz``: a quick look at a run's outputs (time series, spectrograms of vibrations, force-speed trace).

Units come from the units the recording stores (an npz ``units`` entry
holding a JSON object {signal: unit}, a CSV ``# units:`` line, HDF5 ``unit``
attributes, or ``<signal>__unit`` entries), else
they are guessed from the signal's name. Needs matplotlib (the ``plot``
extra); without it the command says how to install it.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

PLOT_LIMIT = 1e150
"""Largest magnitude drawn, in the signal's unit. Beyond it matplotlib's axis arithmetic overflows (a signal reaching
1.7e308 was an internal error) and squares overflow to inf (spectrogram PSDs, 3-axis magnitudes: a blown-up output
drew as a blank spectrogram and an empty force-speed panel, without a word). No measured signal comes near it."""

GUESSES = (("vibration", "m/s^2"), ("accel", "m/s^2"), ("force", "N"), ("velocity", "mm/s"), ("speed", "mm/s"),
           ("position", "mm"), ("in_contact", ""))


def signal_units(arrays: dict[str, np.ndarray], stored: dict[str, str] | None = None) -> dict[str, str]:
    """Unit of every signal: the units the recording stores (``stored``: Recording.units, or the file's metadata
    entries), else guessed by name ('' if unknown)."""
    meta: dict[str, str] = dict(stored or {})
    if "units" in arrays:
        try:
            meta = dict(json.loads(str(np.asarray(arrays["units"]).item()))) | meta
        except (ValueError, TypeError):
            pass
    out = {}
    for name in arrays:
        if name in ("units", "rate") or name.endswith("__unit"):
            continue
        if f"{name}__unit" in arrays:
            out[name] = str(np.asarray(arrays[f"{name}__unit"]).item())
        elif name in meta:
            out[name] = str(meta[name])
        else:
            out[name] = next((u for key, u in GUESSES if key in name.lower()), "")
    return out


def plot_recording(file: str | Path, signals: list[str] | None, output: str | Path,
                   warn: Callable[[str], None] | None = None) -> int:
    """Draw ``signals`` (default: all) of the recording ``file`` into the PNG ``output`` (atomically); returns how many.

    ``warn`` gets one line per signal with values not drawn (:func:`drawable`)."""
    from .errors import FlowtexError
    from .io.figures import agg_pyplot
    from .io.recordings import load_recording

    agg_pyplot("flowtex plot needs matplotlib: pip install 'flowtex[plot]'")
    rec = load_recording(file)
    arrays = dict(rec.arrays)
    units = signal_units(arrays, rec.units)
    names = signals or list(units)
    unknown = [n for n in names if n not in units]
    if unknown:
        raise FlowtexError(f"{file}: no signal {', '.join(unknown)}; it has {', '.join(units)}")
    plot_signals({n: np.asarray(arrays[n], dtype=np.float64) for n in names}, {n: units[n] for n in names}, rec.rate or 1000.0,
                 Path(output), title=Path(file).name, warn=warn)
    return len(names)


def _magnitude(x: np.ndarray) -> np.ndarray:
    return np.linalg.norm(x.reshape(x.shape[0], -1), axis=1) if x.ndim > 1 and x.shape[1] > 1 else x.ravel()


def drawable(signals: dict[str, np.ndarray], rate: float) -> tuple[dict[str, np.ndarray], list[str]]:
    """(the signals with every value beyond +-:data:`PLOT_LIMIT` (inf included) as NaN, which no panel draws; one line
    per signal that had such values, naming how many and the first one's time in s)."""
    out, lines = {}, []
    for name, x in signals.items():
        x = np.asarray(x, dtype=np.float64)
        beyond = np.abs(x) > PLOT_LIMIT
        if np.any(beyond):
            rows = np.flatnonzero(beyond.reshape(x.shape[0], -1).any(axis=1))
            x = np.where(beyond, np.nan, x)
            lines.append(f"signal {name!r}: {rows.size} sample(s) beyond +-{PLOT_LIMIT:g} (or infinite) are not drawn, "
                         f"the first at {rows[0] / rate:g} s (sample {rows[0]})")
        out[name] = x
    return out, lines


def plot_signals(signals: dict[str, np.ndarray], units: dict[str, str], rate: float, path: Path, title: str = "",
                 warn: Callable[[str], None] | None = None) -> None:
    """Write :func:`signals_figure` to the PNG ``path`` (atomically); ``warn`` gets :func:`drawable`'s lines."""
    from .io.figures import save_png

    save_png(signals_figure(signals, units, rate, title, warn), path)


def signals_figure(signals: dict[str, np.ndarray], units: dict[str, str], rate: float, title: str = "",
                   warn: Callable[[str], None] | None = None) -> Any:
    """The figure: one time-series row per signal, a spectrogram row per vibration, a force-speed panel when possible.

    The force-speed panel takes the first signal whose unit is a speed (:func:`~flowtex.io.recording_rules.is_speed_unit`:
    mm/s, m/s, cm/s, um/s in any spelling ``simplify_unit`` reads) against the force (N, mN or kN: ``force``, else the
    first whose name says normal, else the first), and a vibration is
    any signal in m/s^2, g or mm/s^2 (:func:`~flowtex.io.recording_rules.is_unit_of`); each axis is in the unit it is
    stated in (nothing is converted).
    A vibration's spectrogram (:func:`~flowtex.dsp.spectral.spectrogram_psd`) sums the PSDs of its axes, each
    segment's mean removed.

    Laid out by matplotlib's constrained layout, so the title never covers the first panel however many rows there
    are. The time panels share one time axis from 0 to the recording's length (s); each spectrogram's colorbar has a
    column of its own, so every time panel has the same width and their times line up. Values beyond
    +-:data:`PLOT_LIMIT` are not drawn, and ``warn`` (when given) gets a line per signal that had them.
    """
    import matplotlib.pyplot as plt

    from .dsp.spectral import spectrogram_psd
    from .io.figures import FONT_PT, figure_text
    from .io.recording_rules import is_speed_unit, is_unit_of

    signals, lines = drawable(signals, rate)
    for line in lines if warn is not None else ():
        warn(line)
    # each in its stated unit: an acceleration in m/s^2, g or mm/s^2; a speed in m/s, cm/s, mm/s ...; a force in N, mN, kN
    vib = [n for n in signals if is_unit_of(units[n], "m/s^2")]
    speed = next((n for n in signals if is_speed_unit(units[n])), None)
    forces = [n for n in signals if is_unit_of(units[n], "N")]
    # the normal force before any other (a tangential or texture force listed first is not the trace's operating point)
    force = "force" if "force" in forces else next((n for n in forces if "normal" in n.lower()), forces[0] if forces else None)
    rows = len(signals) + len(vib) + (1 if speed and force else 0)
    fig = plt.figure(figsize=(10, 2.0 * rows + 0.6), layout="constrained")
    grid = fig.add_gridspec(rows, 2, width_ratios=(1, 0.015))
    duration = max(x.shape[0] for x in signals.values()) / rate
    time_axes: list[Any] = []

    def time_panel(row: int) -> Any:
        ax = fig.add_subplot(grid[row, 0], sharex=time_axes[0] if time_axes else None)
        time_axes.append(ax)
        ax.set_xlabel("time (s)", fontsize=FONT_PT)
        return ax

    k = 0
    for name, x in signals.items():
        t = np.arange(x.shape[0]) / rate
        ax = time_panel(k)
        x2 = x.reshape(x.shape[0], -1)
        for c in range(x2.shape[1]):
            ax.plot(t, x2[:, c], lw=0.6, label="xyz"[c] if x2.shape[1] == 3 else None)
        if x2.shape[1] == 3:  # beside the panel, never over its data
            ax.legend(loc="upper left", bbox_to_anchor=(1.002, 1.0), fontsize=FONT_PT, borderaxespad=0.0, handlelength=1.2)
        ax.set_ylabel(figure_text(f"{name}\n[{units[name] or '-'}]"), fontsize=FONT_PT)
        ax.grid(alpha=0.3)
        k += 1
    for name in vib:
        ax = time_panel(k)
        f, tt, S = spectrogram_psd(signals[name], rate)  # several axes: the sum of their PSDs, never the PSD of |x|
        db = 10.0 * np.log10(np.maximum(S, 1e-30))
        top = float(db.max()) if S.max() > 0 else 0.0
        mesh = ax.pcolormesh(tt, f, db, shading="auto", cmap="magma", vmin=top - 60.0, vmax=top)  # 60 dB range; silence is black
        cbar = fig.colorbar(mesh, cax=fig.add_subplot(grid[k, 1]))
        cbar.set_label(figure_text(f"dB re 1 ({units[name]})^2/Hz"), fontsize=FONT_PT)
        axes_n = signals[name].reshape(signals[name].shape[0], -1).shape[1]
        shown = f"{name}, sum of {axes_n} axes" if axes_n > 1 else name
        ax.set_ylabel(figure_text(f"{shown}\nfrequency (Hz)"), fontsize=FONT_PT)
        k += 1
    time_axes[0].set_xlim(0.0, duration)
    if speed and force:
        ax = fig.add_subplot(grid[k, 0])
        ax.plot(_magnitude(signals[speed]), _magnitude(signals[force]), ".", ms=1.5, alpha=0.5)
        ax.set_xlabel(figure_text(f"|{speed}| ({units[speed]})"), fontsize=FONT_PT)
        ax.set_ylabel(figure_text(f"|{force}| ({units[force]})"), fontsize=FONT_PT)
        ax.grid(alpha=0.3)
    if title:
        fig.suptitle(figure_text(title), fontsize=FONT_PT + 2)
    return fig
