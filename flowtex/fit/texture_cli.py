"""``flowtex fit texture``: recordings of free exploration (or a Romano-2012 grid) -> a texture model set.

One recording: ``flowtex fit texture REC --accel A --speed S --force F -o SURFACE.json``.
Many: ``flowtex fit texture DIR|GLOB ... --out-dir OUT [--workers N | --scheduler tcp://HOST:8786]``
(flowtex.fit.batch). The pipeline is flowtex.fit.texture; docs/fitting.md
describes every option.
"""

from __future__ import annotations

import argparse
import csv
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import DataError
from ..io.recordings import SUFFIXES
from .inputs import atomic_output, check_not_constant, load, signal
from .texture import TextureFit, TextureOptions, fit_grid, fit_texture


@dataclass
class TextureJob:
    """Everything one texture fit needs besides the recording: signal names and options (picklable for Dask)."""

    accel: str = "accel"
    speed: str | None = None
    force: str = "normal_force"
    position: str | None = None
    normal: str | None = None
    rate: float | None = None
    options: TextureOptions | None = None
    render_rate: float | None = None
    material: str | None = None
    allow_misses: bool = False


def speed_from_position(position: np.ndarray, normal: np.ndarray | None, rate: float) -> np.ndarray:
    """Tangential speed (mm/s) from position (mm) with the speed_estimator's math (hatt method, 0.06 mm gate)."""
    from ..dsp.motion import SPEED_ISTATE, SPEED_STATE, SS_NORMAL, butter2_biquad, initial_normal_state, speed_block, speed_params

    n = position.shape[0]
    nrm = np.ascontiguousarray(normal if normal is not None else np.tile([0.0, 0.0, 1.0], (n, 1)), dtype=np.float64)
    p = speed_params(butter2_biquad(125.0, rate), rate, 0.06)
    s = initial_normal_state(SPEED_STATE, SS_NORMAL, (0.0, 0.0, 1.0))
    si = np.zeros(SPEED_ISTATE, np.int64)
    speed = np.empty((n, 1))
    vel = np.empty((n, 3))
    speed_block(p, s, si, np.ascontiguousarray(position, dtype=np.float64), nrm, speed, vel)
    return speed[:, 0]


def read_signals(path: Path, job: TextureJob, need_speed: bool = True) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None, float]:
    """(1-D acceleration, speed, force, rate) of one recording, checked (see flowtex.fit.inputs).

    Grid cells (``need_speed=False``) need only the acceleration: speed and force come from the index.
    """
    rec, rate = load(path, job.rate)
    acc = signal(rec, job.accel, "--accel", (1, 3))
    if acc.ndim == 2:
        from ..dsp.dft321 import dft321

        acc = dft321(acc)
    check_not_constant(acc, f"{path}: signal {job.accel!r} (--accel)")
    if not need_speed:
        return acc, None, None, rate
    force = signal(rec, job.force, "--force")
    speed = None
    if job.speed is not None:
        speed = signal(rec, job.speed, "--speed")
    elif job.position is not None:
        pos = signal(rec, job.position, "--position", (3,))
        nrm = signal(rec, job.normal, "--normal", (3,)) if job.normal is not None else None
        speed = speed_from_position(pos, nrm, rate)
    else:
        raise DataError(f"{path}: give the tool's speed with --speed S (mm/s) or --position P (mm, 3 axes)")
    return acc, speed, force, rate


def fit_recording(path: Path, job: TextureJob) -> TextureFit:
    """Fit one free-exploration recording."""
    acc, speed, force, rate = read_signals(path, job)
    assert speed is not None and force is not None
    material = job.material or path.stem
    return fit_texture(acc, speed, force, rate, job.options, material, str(path))


def fit_grid_index(index: Path, job: TextureJob) -> TextureFit:
    """Fit a grid: ``index`` is a CSV with columns file, speed (mm/s), force (N); files relative to it."""
    try:
        with index.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except OSError as exc:
        raise DataError(f"{index}: cannot read the grid index ({exc.strerror or exc})") from None
    if not rows or not {"file", "speed", "force"} <= set(rows[0]):
        raise DataError(f"{index}: a grid index needs a header row with columns file, speed, force and one row per recording")
    cells = []
    rate = None
    for k, row in enumerate(rows, start=2):
        try:
            s, f = float(row["speed"]), float(row["force"])
        except (TypeError, ValueError):
            raise DataError(f"{index}:{k}: speed and force must be numbers (mm/s, N)") from None
        acc, _speed, _force, r = read_signals(index.parent / row["file"], job, need_speed=False)
        if rate is not None and r != rate:
            raise DataError(f"{index}:{k}: {row['file']} is at {r:g} Hz but the others are at {rate:g} Hz")
        rate = r
        cells.append((acc, s, f))
    assert rate is not None
    return fit_grid(cells, rate, job.options, job.material or index.stem, str(index))


def write_outputs(fit: TextureFit, output: Path, xml: Path | None, render_rate: float | None, allow_misses: bool = False) -> None:
    """Write the native set (and HaTT XML) atomically, after resampling to ``render_rate`` if given.

    A resampled set with models that miss their spectrum is refused (FlowtexError naming them) unless ``allow_misses``.
    """
    from ..io.hatt import write_hatt_xml
    from ..io.modelset import save_model_set

    ms = fit.model_set
    if render_rate is not None and render_rate != ms.sample_rate:
        ms = _resample(ms, render_rate, allow_misses, str(output))
    with atomic_output(output) as tmp:
        save_model_set(ms, tmp)
        if xml is not None:
            with atomic_output(xml) as tmp_xml:
                write_hatt_xml(ms, tmp_xml)


def _resample(ms: Any, rate: float, allow_misses: bool, where: str) -> Any:
    """The set at ``rate`` Hz (flowtex models resample's method), with a one-line account of what it cost."""
    from .resample import check_misses, resample_model_set, tqdm_progress

    progress, close = tqdm_progress(ms.num_models, "resample")
    try:
        out = resample_model_set(ms, rate, progress)
    finally:
        close()
    warning = check_misses(out, allow_misses, where)
    info = out.metadata["resample"]
    print(f"resampled {info['from_hz']:g} Hz -> {info['to_hz']:g} Hz: orders {ms.ar_order}/{ms.ma_order} -> "
          f"{out.ar_order}/{out.ma_order}, worst LSD {info['worst_lsd_db']:.2f} dB, "
          f"worst band-power error {100 * info['worst_band_power_error']:.2f} %")
    if warning:
        print(warning)
    return out


def parse_order(text: str) -> tuple[int, int] | None:
    if text == "auto":
        return None
    try:
        p, q = (int(v) for v in text.split(","))
    except ValueError:
        raise DataError(f"--order must be auto or P,Q (e.g. 10,8), got {text!r}") from None
    if p < 1 or q < 0:
        raise DataError(f"--order {text}: the AR order must be >= 1 and the MA order >= 0")
    return p, q


def job_from_args(args: argparse.Namespace) -> TextureJob:
    opt = TextureOptions(order=parse_order(args.order), max_order=args.max_order, highpass_hz=args.highpass)
    return TextureJob(accel=args.accel, speed=args.speed, force=args.force, position=args.position, normal=args.normal,
                      rate=args.rate, options=opt, render_rate=args.render_rate, material=args.material,
                      allow_misses=args.allow_misses)


def run(args: argparse.Namespace) -> int:
    from .report import print_table, write_report

    job = job_from_args(args)
    if args.xml == Path("-") and args.output is not None:
        args.xml = args.output.with_suffix(".xml")
    if args.grid is not None:
        if args.recordings:
            raise DataError("--grid INDEX.csv names the recordings itself; give no REC arguments with it")
        if args.output is None:
            raise DataError("--grid needs -o SURFACE.json")
        fit = fit_grid_index(Path(args.grid), job)
        print_table(fit)
        write_outputs(fit, args.output, args.xml, job.render_rate, job.allow_misses)
        if args.report:
            write_report(fit, Path(args.report))
        print(f"-> {args.output}")
        return 0
    from .batch import expand_inputs, fit_many

    paths = expand_inputs(args.recordings)
    if args.out_dir is not None:
        return fit_many(paths, job, Path(args.out_dir), args.workers, args.scheduler, args.xml is not None, args.report is not None)
    if len(paths) != 1:
        raise DataError(f"{len(paths)} recordings given; fit several with --out-dir OUT (one surface file each), or give one with -o")
    if args.output is None:
        raise DataError("give -o SURFACE.json (or --out-dir OUT for many recordings)")
    fit = fit_recording(paths[0], job)
    print_table(fit)
    write_outputs(fit, args.output, args.xml, job.render_rate, job.allow_misses)
    if args.report:
        write_report(fit, Path(args.report))
    print(f"-> {args.output}" + (f", {args.xml}" if args.xml else ""), file=sys.stdout)
    return 0


def register_fit(kinds: Any) -> None:
    """Add ``flowtex fit texture``."""
    p = kinds.add_parser("texture", help="texture model set (ARMA models over speed and force) from free exploration",
                         description="Segment free exploration into stationary pieces, fit one ARMA model per piece at one "
                                     "order shared by the material, and assemble a Delaunay model set (docs/fitting.md).")
    p.add_argument("recordings", nargs="*", help=f"recording(s) ({', '.join(SUFFIXES)}), folders or glob patterns")
    p.add_argument("--accel", default="accel", metavar="A", help="acceleration signal (m/s^2): 1-D, or 3 axes reduced by DFT321")
    p.add_argument("--speed", metavar="S", help="tangential speed signal (mm/s)")
    p.add_argument("--force", default="normal_force", metavar="F", help="normal force signal (N)")
    p.add_argument("--position", metavar="P", help="tool position (mm, 3 axes): speed from it, as speed_estimator does")
    p.add_argument("--normal", metavar="N", help="surface normal signal (3 axes) for --position (default +z)")
    p.add_argument("--rate", type=float, help="sample rate (Hz) when the file states none")
    p.add_argument("--order", default="auto", help="auto (BIC, shared by all pieces) or P,Q")
    p.add_argument("--max-order", type=int, default=20, help="largest p and q searched by --order auto")
    p.add_argument("--highpass", type=float, default=10.0, metavar="HZ", help="zero-phase high-pass of the acceleration (0: none)")
    p.add_argument("--render-rate", type=float, metavar="HZ", help="resample the models to this rate before writing")
    p.add_argument("--allow-misses", action="store_true",
                   help="with --render-rate: write the set even if some resampled model misses its spectrum (else refused)")
    p.add_argument("--material", help="surface name (default: the file's stem)")
    p.add_argument("-o", "--output", type=Path, help="output model set (native JSON)")
    p.add_argument("--xml", type=Path, help="also write HaTT XML (with --out-dir: one .xml beside each .json)", nargs="?",
                   const=Path("-"))
    p.add_argument("--report", metavar="DIR", help="write a markdown report with plots here")
    p.add_argument("--grid", metavar="INDEX.csv", help="Romano-2012 grid: CSV of file, speed, force (one stationary recording each)")
    p.add_argument("--out-dir", metavar="OUT", help="fit every recording given into OUT/<name>.json")
    p.add_argument("--workers", type=int, help="Dask workers on this machine for --out-dir (default: one per core)")
    p.add_argument("--scheduler", metavar="tcp://HOST:8786", help="use this running Dask scheduler for --out-dir")
    p.set_defaults(func=run)
