"""Fit reports: the table every texture fit prints, and ``--report DIR`` (markdown + PNG plots).

Model numbers are the models' indices in the written set (the JSON's arrays,
0-based), in the table, the plots and the report alike. Per model: speed (mm/s), force (N), samples, order (p, q), GFC (Culbertson et al. 2012's
definition, 1 = same spectral shape), LSD in dB (model PSD against the
piece's Welch PSD, 256-point segments: > 15 Hz, 40 dB range) and the power
error in dB (model output power over its piece's variance). The LSD against the data
includes the Welch estimate's own scatter (about 4.3 / sqrt(segments) dB),
so short pieces score worse than their models are; accuracy against a known
truth is measured in tests/fit.

``spectra.png``: one panel per model, its PSD (model) over its piece's Welch
PSD (data), with a legend and the panel's LSD and GFC. ``plane.png``: the
models in the (speed, force) plane over the recorded path, near-duplicate
models (closer than :data:`NEAR_DUPLICATE` of the set's range on both axes)
circled: their triangles are thin and the surface can jump between them. With
``--holdout``/``--folds`` the report adds the held-out comparison.

Plots need matplotlib (the ``plot`` extra); without it the report is written
without them and a one-line hint says how to get them.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..dsp.spectral import expected_lsd_db, welch_psd
from ..io.atomic import write_text_atomic
from ..io.figures import FONT_PT as FONT
from ..io.figures import agg_pyplot, save_png
from ..limits import signed
from ..models.texture import TextureModelSet
from .crossval import POOLED_LINE
from .texture import PIECE_NPERSEG, TextureFit

PLOT_HINT = "plots need matplotlib: pip install 'flowtex[plot]'"
NEAR_DUPLICATE = 0.02
"""Two models are near-duplicates when they lie closer than this fraction of the set's max speed and max force."""


@dataclass
class HeldOut:
    """A held-out comparison for the report: the line naming the split, one Comparison per fold, the JSON document."""

    line: str
    comparisons: list[Any]
    doc: dict[str, Any]


def _by_model(fit: TextureFit) -> list[Any]:
    """The pieces in model order (the set's indices), the longest piece first where two share a model."""
    return sorted(fit.pieces, key=lambda pc: (pc.model, -pc.samples))


def lsd_floor_db(fit: TextureFit, piece: Any) -> float:
    """The LSD (dB) the piece's true spectrum would score against the piece's own Welch estimate (Gaussian data):
    the part of the table's LSD that no model can remove (:func:`flowtex.dsp.spectral.expected_lsd_db`)."""
    return expected_lsd_db(piece.samples, fit.rate, PIECE_NPERSEG)


def table_lines(fit: TextureFit) -> list[str]:
    """The fit table, one line per model (header first, with the units of speed and force). "LSD floor": what a
    perfect model would score against so short a piece (:func:`lsd_floor_db`)."""
    lines = [f"{'model':>5} {'speed mm/s':>10} {'force N':>7} {'samples':>7} {'order':>7} {'GFC':>6} {'LSD dB':>7} "
             f"{'LSD floor':>9} {'power dB':>8}"]
    for pc in _by_model(fit):
        f = pc.fit
        assert f is not None
        lines.append(f"{pc.model:5d} {pc.speed:10.1f} {pc.force:7.2f} {pc.samples:7d} {f'{f.order[0]},{f.order[1]}':>7} {f.gfc:6.3f} "
                     f"{pc.lsd_db:7.2f} {lsd_floor_db(fit, pc):9.2f} {f.power_error_db:+8.2f}")
    return lines


def summary_line(fit: TextureFit) -> str:
    ms = fit.model_set
    lsd = [pc.lsd_db for pc in fit.pieces]
    floor = np.median([lsd_floor_db(fit, pc) for pc in fit.pieces])
    dropped = ", ".join(f"{v} {k}" for k, v in fit.dropped.items() if v) or "none"
    pool = int(ms.metadata.get("pool_pieces", 1))
    pooled = f" (each model on its piece and the {pool - 1} nearest, --pool {pool})" if pool > 1 else ""
    return (f"{ms.material}: {len(fit.pieces)} pieces fitted at order {ms.ar_order},{ms.ma_order}{pooled}; {ms.num_models} models "
            f"(with silent corners), {len(ms.triangles)} triangles; median LSD {np.median(lsd):.2f} dB (a perfect model: {floor:.2f}, "
            f"the pieces' own Welch scatter); dropped: {dropped}; "
            f"clipped outliers: {fit.clipped}")


EDGE_WARN_DB = 1.0
"""A fit whose pieces lie this many dB below the pieces with their edge trims gets a warning (:func:`edge_warning`)."""


def edge_warning(fit: TextureFit) -> str | None:
    """A warning when the pieces' edge trims were louder than the pieces (loud bursts at piece boundaries, cut with the
    transitions): the models then carry a level below the recording's, and nothing else in the fit says so."""
    if not fit.edge_level_db < -EDGE_WARN_DB:
        return None
    return (f"{fit.model_set.material}: the ends cut off each piece (the transitions) were louder than the pieces: the "
            f"models carry a level {-fit.edge_level_db:.1f} dB below that of the pieces with their ends, and the surface "
            "renders about that much quieter than the recording (loud bursts at the piece boundaries; flowtex compare "
            "measures it)")


def print_table(fit: TextureFit) -> None:
    for line in table_lines(fit):
        print(line)
    print(summary_line(fit))
    warning = edge_warning(fit)
    if warning:
        print(f"warning: {warning}", file=sys.stderr)


def near_duplicates(ms: Any) -> list[tuple[int, int]]:
    """Pairs (i, j) of measured models closer than NEAR_DUPLICATE x (max speed, max force) on both axes."""
    idx = np.flatnonzero(ms.variance > 0)
    out = []
    for a, i in enumerate(idx):
        for j in idx[a + 1:]:
            if abs(ms.speeds[i] - ms.speeds[j]) < NEAR_DUPLICATE * ms.max_speed and \
                    abs(ms.forces[i] - ms.forces[j]) < NEAR_DUPLICATE * ms.max_force:
                out.append((int(i), int(j)))
    return out


def held_out_lines(held: HeldOut) -> list[str]:
    """The held-out section of the report: the split, one row per fold (with its surface's in-sample LSD on its own
    training blocks), the mean, the pooled comparison."""
    def row(name: str, r: dict) -> str:
        def f(v: Any, fmt: str) -> str:
            return "null" if v is None else format(v, fmt)
        own = r.get("in_sample") or {}
        return (f"| {name} | {f(r['seconds'], '.1f')} | {f(r['power_ratio_db'], '+.2f')} | {f(r['lsd_db'], '.2f')} | "
                f"{f(own.get('lsd_db'), '.2f') if own else '-'} | {f(r['gfc'], '.3f')} | {f(r['rms_correlation'], '.2f')} |")
    windows = held.doc["results"][0].get("windows") or [{}]
    window = f"{windows[0]['seconds']:g}-s " if "seconds" in windows[0] else ""
    md = ["## Held out", "", held.line, "",
          f"| fold | seconds | power ratio dB | LSD dB | in-sample LSD dB | GFC | {window}window-RMS correlation |",
          "|---|---|---|---|---|---|---|"]
    md += [row(str(k), r) for k, r in enumerate(held.doc["results"])]
    if len(held.doc["results"]) > 1:
        md.append(row("mean", held.doc["mean"]))
    if held.doc.get("pooled") is not None:
        md += [row("pooled", held.doc["pooled"]), "", f"pooled: {POOLED_LINE}."]
    bands = held.doc["mean"].get("octave_bands") or []
    if bands:
        md += ["", "Octave-band power error (rendered over recorded, dB, mean over folds): "
               + ", ".join(f"{b['centre_hz']:g} Hz {signed(b['error_db'], 1)}" for b in bands if b.get("error_db") is not None)]
    warnings = sorted({w for c in held.comparisons for w in c.warnings})
    md += [f"- warning: {w}" for w in warnings]
    return md + [""]


def written_lines(fit: TextureFit, written: TextureModelSet | None) -> list[str]:
    """What the report says of a set written otherwise than fitted (``fit texture --render-rate``: resampled, models
    added between the fitted ones): its rate, orders, models and triangles, so that the report's numbers are not read
    as the file's. Nothing when the set was written as fitted."""
    ms = fit.model_set
    if written is None or written is ms:
        return []
    return [f"Written at {written.sample_rate:g} Hz (--render-rate): resampled from {ms.sample_rate:g} Hz, orders "
            f"{ms.ar_order},{ms.ma_order} -> {written.ar_order},{written.ma_order}, {written.num_models} models "
            f"({written.num_models - ms.num_models} added between the fitted ones), {len(written.triangles)} triangles. "
            f"The table and the figures show the models as fitted, at {ms.sample_rate:g} Hz; the models keep their "
            "numbers in the file.", ""]


REPORT_FILES = ("report.md", "spectra.png", "plane.png")
"""The files :func:`write_report` writes into its folder (no other output of the command may be one of them)."""


def write_report(fit: TextureFit, folder: Path, held: HeldOut | None = None,
                 written: TextureModelSet | None = None) -> Path:
    """Write ``folder/report.md`` and, with matplotlib, ``spectra.png`` and ``plane.png``; returns the markdown path.
    ``written``: the set the fit wrote, when it differs from the fitted one (:func:`written_lines`)."""
    folder.mkdir(parents=True, exist_ok=True)
    warning = edge_warning(fit)
    md = [f"# Texture fit: {fit.model_set.material}", "", summary_line(fit), "", *([f"Warning: {warning}.", ""] if warning else []),
          *written_lines(fit, written), "```",
          *table_lines(fit), "```", ""]
    dups = near_duplicates(fit.model_set)
    if dups:
        md += ["Near-duplicate models (closer than 2 % of the range on both axes): "
               + ", ".join(f"{i} and {j}" for i, j in dups), ""]
    if held is not None:
        md += held_out_lines(held)
    plt = agg_pyplot(None)
    if plt is None:
        print(PLOT_HINT)
        md.append(f"(no plots: {PLOT_HINT})")
    else:
        _plot_spectra(fit, folder / "spectra.png", plt)
        _plot_plane(fit, folder / "plane.png", plt, dups)
        md += ["## Each model's spectrum over its data's", "", "![spectra](spectra.png)", "",
               "## Models in the (speed, force) plane", "", "![plane](plane.png)", ""]
    return write_text_atomic(folder / "report.md", "\n".join(md) + "\n")


def _plot_spectra(fit: TextureFit, path: Path, plt: Any) -> None:
    save_png(spectra_figure(fit, plt), path)


def _plot_plane(fit: TextureFit, path: Path, plt: Any, dups: list[tuple[int, int]]) -> None:
    save_png(plane_figure(fit, plt, dups), path)


def spectra_figure(fit: TextureFit, plt: Any) -> Any:
    """One panel per model: its PSD over its piece's Welch PSD, the model's point, LSD and GFC in the panel's title
    (nothing drawn over the curves), one legend for all panels above them."""
    pieces = _by_model(fit)
    n = len(pieces)
    cols = min(4, n)
    rows = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(3.6 * cols, 3.0 * rows + 0.4), squeeze=False, sharex=True,
                             layout="constrained")
    for k, pc in enumerate(pieces):
        ax = axes[k // cols][k % cols]
        x = fit.signal[pc.start:pc.stop]
        freqs, s = welch_psd(x, fit.rate, PIECE_NPERSEG, whole=True)  # the piece as the table's LSD measures it
        ax.semilogy(freqs, s, color="0.55", lw=0.9, label="data (the piece's Welch PSD)")
        ax.semilogy(freqs, pc.fit.psd(freqs, fit.rate), color="C0", lw=1.3, label="model")
        ax.set_title(f"model {pc.model}: {pc.speed:.0f} mm/s, {pc.force:.2f} N\nLSD {pc.lsd_db:.2f} dB, GFC {pc.fit.gfc:.3f}",
                     fontsize=FONT)
        ax.tick_params(labelsize=FONT)
        ax.tick_params(axis="x", labelbottom=True)  # every panel keeps its frequencies, not only the bottom row
    for k in range(n, rows * cols):
        axes[k // cols][k % cols].axis("off")
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside upper center", ncols=2, fontsize=FONT + 1, frameon=False)
    fig.supxlabel("frequency (Hz)", fontsize=FONT + 1)
    fig.supylabel("PSD ((m/s^2)^2/Hz)", fontsize=FONT + 1)
    return fig


def plane_figure(fit: TextureFit, plt: Any, dups: list[tuple[int, int]]) -> Any:
    """The models in the (speed, force) plane over the recorded path and the triangulation, coloured by power; the
    legend below the axes, clear of the models."""
    ms = fit.model_set
    fig, ax = plt.subplots(figsize=(7, 5.8), layout="constrained")
    if fit.path is not None:
        # a colour of its own: in grey it could not be told from the triangles' edges
        ax.plot(fit.path[:, 0], fit.path[:, 1], color="C1", alpha=0.45, lw=0.8, zorder=1, label="recorded path")
    ax.triplot(ms.speeds, ms.forces, ms.triangles, color="0.55", lw=0.6, zorder=2, label="triangulation")
    measured = ms.variance > 0
    pieces = _by_model(fit)
    power = np.array([pc.fit.output_variance for pc in pieces])
    pts = np.array([[pc.speed, pc.force] for pc in pieces])
    sc = ax.scatter(pts[:, 0], pts[:, 1], c=10 * np.log10(power), cmap="viridis", s=36, zorder=3)
    below = {j for _i, j in dups}  # the second of a near-duplicate pair labelled below left: not over the first's number
    for pc in pieces:
        low = pc.model in below
        ax.annotate(str(pc.model), (pc.speed, pc.force), fontsize=FONT, xytext=(-3, -3) if low else (3, 3),
                    textcoords="offset points", ha="right" if low else "left", va="top" if low else "bottom")
    ax.scatter(ms.speeds[~measured], ms.forces[~measured], marker="x", color="k", s=20, label="silent corner (variance 0)")
    if dups:
        idx = sorted({i for pair in dups for i in pair})
        ax.scatter(ms.speeds[idx], ms.forces[idx], s=160, facecolors="none", edgecolors="C3", lw=1.5, zorder=4,
                   label=f"near-duplicate models (< {100 * NEAR_DUPLICATE:g} % apart)")
    cb = fig.colorbar(sc)
    cb.set_label("model power (dB re 1 (m/s^2)^2)", fontsize=FONT + 1)
    cb.ax.tick_params(labelsize=FONT)
    ax.set_xlabel("speed (mm/s)", fontsize=FONT + 1)
    ax.set_ylabel("normal force (N)", fontsize=FONT + 1)
    ax.tick_params(labelsize=FONT)
    handles, labels = ax.get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=FONT, loc="outside lower center", ncols=min(3, len(labels)), frameon=False)
    return fig
