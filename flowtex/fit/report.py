"""Fit reports: the table every texture fit prints, and ``--report DIR`` (markdown + PNG plots).

Per model: speed (mm/s), force (N), samples, order (p, q), GFC (Culbertson et al. 2012's
definition, 1 = same spectral shape), LSD in dB (model PSD against the
piece's Welch PSD, 256-point segments: > 15 Hz, 40 dB range) and the power
error (model output power / data variance - 1). The LSD against the data
includes the Welch estimate's own scatter (about 4.3 / sqrt(segments) dB),
so short pieces score worse than their models are; accuracy against a known
truth is measured in tests/fit.

Plots need matplotlib (the ``plot`` extra); without it the report is written
without them and a one-line hint says how to get them.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..dsp.spectral import welch_psd
from ..io.atomic import write_text_atomic
from ..io.figures import agg_pyplot, save_png
from .texture import TextureFit

PLOT_HINT = "plots need matplotlib: pip install 'flowtex[plot]'"


def table_lines(fit: TextureFit) -> list[str]:
    """The fit table, one line per model (header first)."""
    lines = [f"{'model':>5} {'speed':>8} {'force':>6} {'samples':>7} {'order':>7} {'GFC':>6} {'LSD dB':>7} {'power err':>9}"]
    for k, pc in enumerate(fit.pieces):
        f = pc.fit
        assert f is not None
        lines.append(f"{k:5d} {pc.speed:8.1f} {pc.force:6.2f} {pc.samples:7d} {f.order[0]:3d},{f.order[1]:<3d} {f.gfc:6.3f} "
                     f"{pc.lsd_db:7.2f} {100 * f.power_error:8.2f}%")
    return lines


def summary_line(fit: TextureFit) -> str:
    ms = fit.model_set
    lsd = [pc.lsd_db for pc in fit.pieces]
    dropped = ", ".join(f"{v} {k}" for k, v in fit.dropped.items() if v) or "none"
    return (f"{ms.material}: {len(fit.pieces)} pieces fitted at order {ms.ar_order},{ms.ma_order}; {ms.num_models} models "
            f"(with silent corners), {len(ms.triangles)} triangles; median LSD {np.median(lsd):.2f} dB; dropped: {dropped}; "
            f"clipped outliers: {fit.clipped}")


def print_table(fit: TextureFit) -> None:
    for line in table_lines(fit):
        print(line)
    print(summary_line(fit))


def write_report(fit: TextureFit, folder: Path) -> Path:
    """Write ``folder/report.md`` and, with matplotlib, ``spectra.png`` and ``plane.png``; returns the markdown path."""
    folder.mkdir(parents=True, exist_ok=True)
    md = [f"# Texture fit: {fit.model_set.material}", "", summary_line(fit), "", "```", *table_lines(fit), "```", ""]
    plt = agg_pyplot(None)
    if plt is None:
        print(PLOT_HINT)
        md.append(f"(no plots: {PLOT_HINT})")
    else:
        _plot_spectra(fit, folder / "spectra.png", plt)
        _plot_plane(fit, folder / "plane.png", plt)
        md += ["## Each model's spectrum over its data's", "", "![spectra](spectra.png)", "",
               "## Models in the (speed, force) plane", "", "![plane](plane.png)", ""]
    return write_text_atomic(folder / "report.md", "\n".join(md) + "\n")


def _plot_spectra(fit: TextureFit, path: Path, plt) -> None:
    n = len(fit.pieces)
    cols = min(6, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3 * cols, 2.2 * rows), squeeze=False, sharex=True)
    for k, pc in enumerate(fit.pieces):
        ax = axes[k // cols][k % cols]
        x = fit.signal[pc.start:pc.stop]
        freqs, s = welch_psd(x, fit.rate, min(256, x.size))
        ax.semilogy(freqs, s, color="0.6", lw=0.8)
        ax.semilogy(freqs, pc.fit.psd(freqs, fit.rate), color="C0", lw=1.0)
        ax.set_title(f"{k}: {pc.speed:.0f} mm/s, {pc.force:.2f} N", fontsize=7)
        ax.tick_params(labelsize=6)
    for k in range(n, rows * cols):
        axes[k // cols][k % cols].axis("off")
    fig.supxlabel("Hz")
    fig.supylabel("(m/s^2)^2/Hz")
    save_png(fig, path)


def _plot_plane(fit: TextureFit, path: Path, plt) -> None:
    ms = fit.model_set
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.triplot(ms.speeds, ms.forces, ms.triangles, color="0.7", lw=0.6)
    measured = ms.variance > 0
    power = np.array([pc.fit.output_variance for pc in fit.pieces])
    pts = np.array([[pc.speed, pc.force] for pc in fit.pieces])
    sc = ax.scatter(pts[:, 0], pts[:, 1], c=10 * np.log10(power), cmap="viridis", s=30, zorder=3)
    ax.scatter(ms.speeds[~measured], ms.forces[~measured], marker="x", color="k", s=20, label="silent corner (variance 0)")
    fig.colorbar(sc, label="model power (dB re 1 (m/s^2)^2)")
    ax.set_xlabel("speed (mm/s)")
    ax.set_ylabel("force (N)")
    ax.legend(fontsize=7, loc="upper left")
    save_png(fig, path)
