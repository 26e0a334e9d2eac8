"""``flowtex compare --report DIR``: a markdown page with the comparison's figures and three plots (matplotlib).

Plots: ``spectrum.png`` (recorded and rendered Welch PSDs, high-passed, start
skipped), ``loudness.png`` (recorded and rendered RMS of each window over
time), ``windows.png`` (LSD and spectral centroids per window) and
``octaves.png`` (rendered over recorded power per octave band, dB).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..io.atomic import write_text_atomic
from ..io.figures import FONT_PT, agg_pyplot, save_png
from ..limits import signed
from .compare import Comparison, correlation_text, summary_lines

PLOT_ERROR = "--report needs matplotlib for its plots: pip install 'flowtex[plot]' (or leave out --report)"


def pyplot() -> Any:
    """matplotlib.pyplot on the Agg backend; DataError naming the ``plot`` extra when matplotlib is missing."""
    return agg_pyplot(PLOT_ERROR)


def write_compare_report(c: Comparison, folder: Path, title: str) -> Path:
    """Write ``folder/report.md`` with the figures, the per-window table and the plots; returns the markdown path."""
    plt = pyplot()
    folder.mkdir(parents=True, exist_ok=True)
    for name, figure in FIGURES.items():
        save_png(figure(c, plt), folder / name)
    md = [f"# {title}", "", "```", *summary_lines(c), "```", "",
          "![spectrum](spectrum.png)", "", "![loudness](loudness.png)", "", "![windows](windows.png)", "",
          "![octaves](octaves.png)", "", *window_table(c)]
    return write_text_atomic(folder / "report.md", "\n".join(md) + "\n")


def window_table(c: Comparison) -> list[str]:
    """The per-window markdown table: RMS in m/s^2 to three significant digits, trailing zeros kept (2.30, not 2.3,
    under 3.06), so that the column reads alike."""
    rows = ["| start s | recorded RMS m/s^2 | rendered RMS m/s^2 | LSD dB | GFC | centroid Hz (rec / ren) |",
            "|---|---|---|---|---|---|"]
    for w in c.windows:
        rms = [f"{w[k]:#.3g}".rstrip(".") for k in ("recorded_rms", "rendered_rms")]
        rows.append(f"| {w['start_s']:.1f} | {rms[0]} | {rms[1]} | {w['lsd_db']:.2f} | "
                    f"{w['gfc']:.3f} | {w['centroid_hz']:.0f} / {w['rendered_centroid_hz']:.0f} |")
    return rows


def _legend_beside(ax: Any) -> None:
    """The legend to the right of the axes (constrained layout makes room): it never covers a curve."""
    ax.legend(fontsize=FONT_PT, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0, frameon=False)


def _window_centres(c: Comparison) -> np.ndarray:
    return np.array([w["start_s"] + 0.5 * w["seconds"] for w in c.windows])


def spectrum_figure(c: Comparison, plt: Any) -> Any:
    fig, ax = plt.subplots(figsize=(7.5, 4), layout="constrained")
    if c.freqs is not None:
        ax.semilogy(c.freqs, c.recorded_psd, color="0.4", lw=1.0, label="recorded")
        ax.semilogy(c.freqs, c.rendered_psd, color="C0", lw=1.0, label=f"rendered\n(mean of {c.seeds})")
    ax.axvspan(c.band_hz[0], c.band_hz[1], color="0.93", zorder=0, label="compared band")
    ax.set_xlabel("frequency (Hz)")
    ax.set_ylabel("PSD ((m/s^2)^2/Hz)")
    ax.set_title(f"power ratio {signed(c.power_ratio_db, 2)} dB (> {c.band_hz[0]:g} Hz), LSD {c.lsd_db:.2f} dB, GFC {c.gfc:.3f} "
                 f"({c.band_hz[0]:g}-{c.band_hz[1]:g} Hz)", fontsize=FONT_PT + 1)  # the power ratio's band is not LSD's
    _legend_beside(ax)
    return fig


def loudness_figure(c: Comparison, plt: Any) -> Any:
    fig, ax = plt.subplots(figsize=(7.5, 3.5), layout="constrained")
    t = _window_centres(c)
    ax.plot(t, [w["recorded_rms"] for w in c.windows], "o-", color="0.4", ms=3, label="recorded")
    ax.plot(t, [w["rendered_rms"] for w in c.windows], "o-", color="C0", ms=3, label="rendered")
    ax.set_xlabel("time (s, window centre)")
    ax.set_ylabel("window RMS (m/s^2)")
    ax.set_title(f"window RMS correlation {correlation_text(c)}", fontsize=FONT_PT + 1)
    _legend_beside(ax)
    return fig


def windows_figure(c: Comparison, plt: Any) -> Any:
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(7.5, 4.5), sharex=True, layout="constrained")
    t = _window_centres(c)
    a1.plot(t, [w["lsd_db"] for w in c.windows], "o-", ms=3, color="C1", label="LSD")
    a1.set_ylabel("LSD (dB)")
    a2.plot(t, [w["centroid_hz"] for w in c.windows], "o-", color="0.4", ms=3, label="recorded")
    a2.plot(t, [w["rendered_centroid_hz"] for w in c.windows], "o-", color="C0", ms=3, label="rendered")
    a2.set_ylabel("centroid (Hz)")
    a2.set_xlabel("time (s, window centre)")
    _legend_beside(a2)
    return fig


def octaves_figure(c: Comparison, plt: Any) -> Any:
    fig, ax = plt.subplots(figsize=(7.5, 3.5), layout="constrained")
    bands = [b for b in c.octave_bands if np.isfinite(b["error_db"])]
    labels = [f"{b['centre_hz']:g}" for b in bands]
    errors = [b["error_db"] for b in bands]
    ax.bar(labels, errors, color=["C3" if e < 0 else "C0" for e in errors])
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set_xlabel("octave band centre (Hz)")
    ax.set_ylabel("rendered / recorded power (dB)")
    ax.set_title(f"power error per octave band ({c.band_hz[0]:g}-{c.band_hz[1]:g} Hz)", fontsize=FONT_PT + 1)
    return fig


FIGURES = {"spectrum.png": spectrum_figure, "loudness.png": loudness_figure, "windows.png": windows_figure,
           "octaves.png": octaves_figure}
"""Each plot of the report: file name -> ``figure(comparison, pyplot)``."""
