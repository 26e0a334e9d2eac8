"""Texture model sets from recordings: preprocess, segment, fit one shared order, assemble the set.

After Kuchenbecker & Culbertson 2014, Culbertson & Kuchenbecker 2017 and Culbertson et al. 2012.

Pipeline of :func:`fit_texture` (units: acceleration m/s^2, speed mm/s, force N):

1. zero-phase 10 Hz Butterworth high-pass (4th order, ``sosfiltfilt``) to remove
   gravity and hand motion (Romano & Kuchenbecker 2012, Culbertson et al. 2012), then isolated spikes beyond 8 robust
   standard deviations are clipped (flowtex.dsp.robust.clamp_outliers);
2. segmentation into stationary pieces (flowtex.dsp.segment: ruptures PELT,
   BIC penalty) - skipped for grid recordings, which are one piece each;
3. pieces are trimmed by ``trim_s`` at both ends (the transitions between
   plateaus), and dropped when shorter than ``min_piece_s``, out of contact
   (median force < ``min_force``) or not moving (median speed < ``min_speed``);
   each kept piece is labelled with its median speed and force (Kuchenbecker & Culbertson 2014).
   A hand never holds speed long: on recordings of drifting speed
   (flowtex.datasets.realistic) 0.5 s pieces with 0.1 s trims dropped 2/3 of
   the pieces, the fast ones among them, and the rendered spectrum lost
   0.47 dB LSD against the true surface's (6 seeds); 0.3 s with 0.05 s trims
   keeps 2.5x as many and loses 0.23 dB. The segmenter's shortest piece is
   ``min_piece_s`` + 2 ``trim_s``, so trimming never makes a piece too short:
   with ``min_piece_s`` alone, every piece of the shortest length was dropped
   after its trims, on drifting recordings with bursts (flowtex.datasets.resonant)
   half of all pieces and, where loudness changes fast, up to 80 % of the
   power, and the surface rendered 5.7 dB too quiet;
4. every piece is fitted at ONE order shared by the material (Culbertson et al. 2012):
   ``order=None`` chooses it (flowtex.fit.arma.select_shared_order, the least
   summed BIC) over the ``order_pieces`` longest pieces - the order is a
   property of the material, and a minute of exploration has some 40 pieces
   whose full search would cost 6 refined fits each - else ``(p, q)``.
   A free exploration's model of a piece is fitted on that piece pooled with
   its ``pool_pieces`` - 1 nearest neighbours in (speed, force), its level
   moved to its own point along the pieces' power law (flowtex.fit.pooling:
   a short piece carries its second's wandering loudness); a grid's cells
   are long and stationary and are fitted alone;
5. the set (:func:`assemble_set`): the measured models, silent corner models
   (variance 0) at speed 0 and force 0 copying their nearest measured model
   (HaTT, Romano & Kuchenbecker 2012), a Delaunay triangulation over (speed, force) and the set's
   maxima (largest measured speed and force).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np

from ..dsp.contact import CONTACT_ON_N
from ..dsp.filter_design import zero_phase_highpass
from ..dsp.lsf_roots import poly_to_lsf
from ..dsp.robust import clamp_outliers
from ..dsp.segment import segment
from ..dsp.spectral import gfc_data_model
from ..errors import DataError, InputError
from ..io.modelset import delaunay_triangles
from ..limits import excerpt
from ..models.rendering import FITTED_RULE
from ..models.texture import TextureModelSet
from .arma import ArmaFit, fit_arma, select_shared_order
from .inputs import api_signals, sample_ranges
from .pooling import neighbour_groups, pooled_data, trend_factors

CORNERS = 8
"""Silent corner models per axis (HaTT's cork surface has 8 at speed 0 and 8 at force 0, plus the origin)."""
POOL_PIECES = 5
"""Default of :attr:`TextureOptions.pool_pieces` (docs/fitting.md, "Pooling neighbouring pieces", has the measurements)."""
PIECE_NPERSEG = 256
"""Welch segment (samples) of a piece's spectrum in the fit table's LSD and the report's figures (whole pieces:
:func:`flowtex.dsp.spectral.welch_psd` with ``whole=True``; a shorter piece is one segment)."""


@dataclass
class TextureOptions:
    """Settings of :func:`fit_texture` (see the module docstring)."""

    order: tuple[int, int] | None = None
    max_order: int = 20
    highpass_hz: float = 10.0
    outlier_sigma: float = 8.0
    frame_s: float = 0.05
    min_piece_s: float = 0.3
    trim_s: float = 0.05
    min_force: float = CONTACT_ON_N
    min_speed: float = 5.0
    penalty_scale: float = 1.0
    order_pieces: int = 8
    pool_pieces: int = POOL_PIECES
    """Pieces each model of a free exploration is fitted on: its own and its nearest neighbours in (speed, force)
    (flowtex.fit.pooling); 1 fits every piece alone."""


@dataclass
class Piece:
    """One stationary piece: samples ``start:stop``, its median speed (mm/s) and force (N), its model and quality."""

    start: int
    stop: int
    speed: float
    force: float
    fit: ArmaFit | None = None
    lsd_db: float = float("nan")
    model: int = -1
    """Index of this piece's model in the set (:func:`assemble_set`; a near-identical point shares the longer piece's)."""

    @property
    def samples(self) -> int:
        return self.stop - self.start


@dataclass
class TextureFit:
    """The fitted set and how it was made (pieces with their data, dropped pieces, clipped samples)."""

    model_set: TextureModelSet
    pieces: list[Piece]
    signal: np.ndarray
    rate: float
    dropped: dict[str, int] = field(default_factory=dict)
    clipped: int = 0
    path: np.ndarray | None = None
    """(n, 2) recorded (speed mm/s, force N) of a free-exploration fit (None for a grid), for the report's plane plot."""
    edge_level_db: float = 0.0
    """:func:`trimmed_level_db` of the pieces: how far their power lies below that of the pieces with their edge trims
    (negative: the trims were louder, and the models carry a level below the recording's)."""


def trimmed_level_db(x: np.ndarray, pieces: Sequence[Piece], trim: int) -> float:
    """Mean power (per sample) of the pieces over that of the pieces with the ``trim`` samples cut at each end, in dB.

    About 0 when the trims are like the pieces. Negative when the segmenter put the pieces' boundaries at loud bursts
    and the trims cut them away with much of the recording's energy: the fit then renders quieter than the recording
    (docs/fitting.md). 0 when there is no power to compare.
    """
    n_in = n_all = 0
    e_in = e_all = 0.0
    for pc in pieces:
        lo, hi = max(0, pc.start - trim), min(x.shape[0], pc.stop + trim)
        e_in += float(np.dot(x[pc.start:pc.stop], x[pc.start:pc.stop]))
        e_all += float(np.dot(x[lo:hi], x[lo:hi]))
        n_in += pc.stop - pc.start
        n_all += hi - lo
    if e_in <= 0.0 or e_all <= 0.0 or n_in == 0:
        return 0.0
    return float(10.0 * np.log10((e_in / n_in) / (e_all / n_all)))


def preprocess(accel: np.ndarray, rate: float, highpass_hz: float = 10.0, outlier_sigma: float = 8.0) -> tuple[np.ndarray, int]:
    """Zero-phase high-pass (sosfiltfilt, 4th-order Butterworth) and outlier clipping; returns (signal, clipped count)."""
    x = zero_phase_highpass(accel, rate, highpass_hz)
    if outlier_sigma > 0:
        x, bad = clamp_outliers(x, outlier_sigma)
        return x, int(bad.size)
    return x, 0


def find_pieces(x: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float, opt: TextureOptions,
                where: str, within: Sequence[tuple[int, int]] | None = None) -> tuple[list[Piece], dict[str, int]]:
    """Segment, trim, drop and label pieces; raises DataError when none is usable.

    ``within``: (start, stop) sample ranges to take pieces from (default: all); each is segmented on its own, so no
    piece straddles two ranges (the one-second blocks of a cross-validation, flowtex.fit.crossval).
    """
    ranges = []
    for lo, hi in (within if within is not None else [(0, x.shape[0])]):
        if hi - lo >= 2:
            ranges += [(lo + a, lo + b) for a, b in segment(x[lo:hi], speed[lo:hi], force[lo:hi], rate, opt.frame_s,
                                                           opt.min_piece_s + 2 * opt.trim_s, opt.penalty_scale)]
    trim = int(round(opt.trim_s * rate))
    min_len = int(round(opt.min_piece_s * rate))
    dropped = {"short": 0, "no contact": 0, "not moving": 0}
    pieces = []
    any_contact = False
    for a, b in ranges:
        a2, b2 = a + trim, b - trim
        if b2 - a2 < min_len:
            dropped["short"] += 1
            continue
        f = float(np.median(force[a2:b2]))
        s = float(np.median(speed[a2:b2]))
        if f < opt.min_force:
            dropped["no contact"] += 1
            continue
        any_contact = True
        if s < opt.min_speed:
            dropped["not moving"] += 1
            continue
        pieces.append(Piece(a2, b2, s, f))
    if not pieces:
        if not np.any(force >= opt.min_force):
            raise DataError(f"{where}: no contact anywhere (the force never reaches {opt.min_force:g} N); "
                            "check --force names the normal force in N")
        why = (f"none is moving: every piece's median speed is below {opt.min_speed:g} mm/s; check --speed is in mm/s"
               if any_contact else "none is in contact long enough")
        if x.shape[0] < min_len + 2 * trim:
            raise DataError(f"{where}: recording too short ({x.shape[0] / rate:.2f} s): a piece needs {opt.min_piece_s:g} s "
                            f"of steady contact plus {opt.trim_s:g} s at each end; record longer")
        raise DataError(f"{where}: no stationary piece of at least {opt.min_piece_s:g} s to fit ({why}; dropped {dropped}); "
                        "record longer plateaus of steady speed and force")
    return pieces, dropped


def fit_pieces(x: np.ndarray, pieces: Sequence[Piece], rate: float, opt: TextureOptions, where: str, pool: int = 1) -> None:
    """Fit every piece at one shared order (chosen over all pieces unless ``opt.order``), in place.

    ``pool``: each piece's model is fitted on it and its ``pool`` - 1 nearest pieces in (speed, force)
    (flowtex.fit.pooling); its LSD is measured against its own samples.
    """
    data = [x[pc.start:pc.stop] for pc in pieces]
    p, q = opt.order if opt.order is not None else (opt.max_order, opt.max_order)
    need = max(10 * (p + q + 1), 100)
    longest = max(d.shape[0] for d in data)
    if longest < need:
        raise DataError(f"{where}: the longest usable piece has {longest} samples ({longest / rate:.2f} s), too short for order "
                        f"up to ({p}, {q}) (needs {need}); record longer plateaus or lower --order/--max-order")
    try:
        order = opt.order
        if order is None:
            longest_first = sorted(range(len(data)), key=lambda k: -data[k].shape[0])[:max(1, opt.order_pieces)]
            order = select_shared_order([data[k] for k in longest_first], opt.max_order)
        groups = neighbour_groups([pc.speed for pc in pieces], [pc.force for pc in pieces], pool)
        fits = [fit_arma(pooled_data(data, g), order) for g in groups]
    except DataError as exc:
        raise DataError(f"{where}: {exc}") from None
    if pool > 1:
        # each group's level moved to its own piece's point; the table's GFC and power error then describe each model
        # against its own piece (the power error: how far pooling moved its level)
        own = [float(np.var(d)) for d in data]
        factors = trend_factors([pc.speed for pc in pieces], [pc.force for pc in pieces], own, [d.shape[0] for d in data], groups)
        fits = [replace(f, variance=f.variance * k, data_variance=v, gfc=gfc_data_model(d - np.mean(d), f.ar, f.ma))
                for f, k, v, d in zip(fits, factors, own, data, strict=True)]
    for pc, d, f in zip(pieces, data, fits, strict=True):
        pc.fit = f
        pc.lsd_db = f.lsd_db(d, rate, PIECE_NPERSEG)


def distinct_points(pieces: Sequence[Piece]) -> tuple[list[Piece], list[Piece]]:
    """(pieces kept, pieces dropped): of several pieces at one (speed, force) point the longest is kept (a model set
    holds one model per point); points closer than 1e-6 of the largest speed and force count as one."""
    scale = np.array([max(pc.speed for pc in pieces), max(pc.force for pc in pieces)])
    scale[scale == 0] = 1.0
    kept: list[Piece] = []
    dropped: list[Piece] = []
    for pc in sorted(pieces, key=lambda pc: -pc.samples):
        pt = np.array([pc.speed, pc.force])
        if kept and np.min(np.sum(((np.array([[k.speed, k.force] for k in kept]) - pt) / scale) ** 2, axis=1)) < 1e-12:
            dropped.append(pc)
        else:
            kept.append(pc)
    return kept, dropped


def assemble_set(pieces: Sequence[Piece], rate: float, material: str, metadata: dict | None = None) -> TextureModelSet:
    """Measured models + silent corners + Delaunay triangulation + maxima (see the module docstring)."""
    pts, ar, ma, var, gain = [], [], [], [], []
    max_speed = max(pc.speed for pc in pieces)
    max_force = max(pc.force for pc in pieces)
    scale = np.array([max_speed, max_force])
    kept, same = distinct_points(pieces)
    for pc in kept:
        pt = np.array([pc.speed, pc.force])
        assert pc.fit is not None
        pc.model = len(pts)
        pts.append(pt)
        ar.append(poly_to_lsf(pc.fit.ar))
        ma.append(poly_to_lsf(pc.fit.ma))
        var.append(pc.fit.variance)
        gain.append(pc.fit.gain)
    for pc in same:  # a piece at the point of a longer one renders with that one's model
        pc.model = int(np.argmin(np.sum(((np.array(pts) - np.array([pc.speed, pc.force])) / scale) ** 2, axis=1)))
    measured = np.array(pts)
    if len(measured) < 2:
        raise DataError(f"{material}: only one distinct (speed, force) point was measured; a model set needs a spread of "
                        "speeds or forces (explore the surface at several speeds and forces)")
    corners = [(0.0, f) for f in np.linspace(max_force / CORNERS, max_force, CORNERS)]
    corners += [(s, 0.0) for s in np.linspace(max_speed / CORNERS, max_speed, CORNERS)] + [(0.0, 0.0)]
    for c in corners:
        src = int(np.argmin(np.sum(((measured - np.array(c)) / scale) ** 2, axis=1)))
        pts.append(np.array(c))
        ar.append(ar[src])
        ma.append(ma[src])
        var.append(0.0)
        gain.append(gain[src])
    points = np.array(pts)
    p = len(ar[0])
    q = len(ma[0])
    ms = TextureModelSet(material=material, sample_rate=float(rate), speeds=points[:, 0].copy(), forces=points[:, 1].copy(),
                         triangles=delaunay_triangles(points, material), ar_lsf=np.array(ar).reshape(len(pts), p),
                         ma_lsf=np.array(ma).reshape(len(pts), q), variance=np.array(var), gain=np.array(gain),
                         max_speed=float(max_speed), max_force=float(max_force), metadata=dict(metadata or {}),
                         rule=FITTED_RULE)
    return ms.validate()


def fit_texture(accel: np.ndarray, speed: np.ndarray, force: np.ndarray, rate: float, opt: TextureOptions | None = None,
                material: str = "surface", where: str = "recording",
                within: Sequence[tuple[int, int]] | None = None) -> TextureFit:
    """Free exploration (1-D acceleration m/s^2, speed mm/s, force N at ``rate`` Hz) -> a texture model set.

    ``within``: fit only the pieces inside these (start, stop) sample ranges. The recording is high-passed whole
    first, so the ranges are never spliced together and no filter transient is made at their edges.
    """
    opt = opt or TextureOptions()
    rate, (accel, speed, force) = api_signals(where, rate, accel=accel, speed=speed, force=force)
    within = sample_ranges(where, "within", within, accel.shape[0])
    x, clipped = preprocess(accel, rate, opt.highpass_hz, opt.outlier_sigma)
    pieces, dropped = find_pieces(x, speed, force, rate, opt, where, within)
    pool = max(1, min(opt.pool_pieces, len(pieces)))
    fit_pieces(x, pieces, rate, opt, where, pool)
    order = pieces[0].fit.order if pieces[0].fit is not None else (0, 0)
    meta = {"fitted_by": "flowtex fit texture", "order": list(order), "pieces": len(pieces), "highpass_hz": opt.highpass_hz,
            "pool_pieces": pool}
    ms = assemble_set(pieces, rate, material, meta)
    return TextureFit(ms, pieces, x, rate, dropped, clipped, np.column_stack([speed, force]).astype(np.float64),
                      trimmed_level_db(x, pieces, int(round(opt.trim_s * rate))))


def fit_grid(cells: Sequence[tuple[np.ndarray, float, float]], rate: float, opt: TextureOptions | None = None,
             material: str = "surface", where: str = "grid") -> TextureFit:
    """Romano 2012's grid: one stationary recording per (speed mm/s, force N) cell -> one model each, one shared order."""
    opt = opt or TextureOptions()
    xs, pieces = [], []
    offset = 0
    clipped = 0
    for k, cell in enumerate(cells):
        if not (isinstance(cell, (list, tuple)) and len(cell) == 3):
            raise InputError(f"{where}: cells[{k}] must be (accel, speed mm/s, force N), got {excerpt(cell)}")
        rate, (accel,) = api_signals(f"{where}: cells[{k}]", rate, accel=cell[0])
        s, f = cell[1], cell[2]
        x, c = preprocess(accel, rate, opt.highpass_hz, opt.outlier_sigma)
        trim = min(int(round(opt.trim_s * rate)), x.shape[0] // 4)
        xs.append(x)
        pieces.append(Piece(offset + trim, offset + x.shape[0] - trim, float(s), float(f)))
        offset += x.shape[0]
        clipped += c
    x = np.concatenate(xs)
    fit_pieces(x, pieces, rate, opt, where)
    order = pieces[0].fit.order if pieces[0].fit is not None else (0, 0)
    ms = assemble_set(pieces, rate, material, {"fitted_by": "flowtex fit texture --grid", "order": list(order)})
    same = Counter(f"cell(s) at ({pc.speed:g} mm/s, {pc.force:g} N), the point of a longer cell whose model was kept"
                   for pc in distinct_points(pieces)[1])
    return TextureFit(ms, pieces, x, rate, dict(same), clipped)
