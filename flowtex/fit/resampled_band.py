"""The band (Hz) whose spectrum a resampled texture model set knows, and what HaTT XML loses of it.

A set resampled from another rate keeps its models' spectra only below a fraction of the lower Nyquist frequency
(flowtex.fit.resample); ``flowtex compare`` grades shapes only there, and writing such a set as HaTT XML, which has no
place for the resampling record, loses that band (docs/fitting.md).
"""

from __future__ import annotations

import math
from pathlib import Path

from ..dsp.resample import PASSBAND as RESAMPLE_PASSBAND
from ..errors import DataError
from ..limits import excerpt
from ..models.texture import TextureModelSet


def resampled_band_hz(ms: TextureModelSet) -> float:
    """The band (Hz) a set resampled from another rate knows: ``RESAMPLE_PASSBAND`` x the lower Nyquist (inf for a
    set at its own rate).

    Resampled up, above it the models hold only a stopband ceiling, and a recording resampled up from that rate with
    ``flowtex resample`` holds only the resampler's transition band; resampled down, the models keep their spectrum
    only up to 0.9 x the new Nyquist and a recording resampled down holds its passband only up to ``RESAMPLE_PASSBAND``
    x it. Comparing shapes above measures neither the fit nor the recording (a resampled twin is compared in the
    common band).
    """
    record = ms.metadata.get("resample") if isinstance(ms.metadata, dict) else None
    from_hz = record.get("from_hz") if isinstance(record, dict) else None
    if record is not None and (not isinstance(record, dict) or from_hz is not None and (
            isinstance(from_hz, bool) or not isinstance(from_hz, (int, float)) or not 0 < from_hz < math.inf)):
        got = excerpt(record if not isinstance(record, dict) else from_hz)
        raise DataError(f"{ms.source or ms.material}: metadata 'resample' must be the record flowtex models resample "
                        f"writes, with from_hz the rate (Hz) the set was resampled from; got {got}: fix or remove it")
    if from_hz is not None and from_hz != ms.sample_rate:
        return RESAMPLE_PASSBAND * min(from_hz, ms.sample_rate) / 2.0
    return math.inf


def band_lost_in_xml(ms: TextureModelSet, path: str | Path) -> str | None:
    """The warning for writing a set resampled from another rate to HaTT XML at ``path`` (None for any other set).

    HaTT's format has no place for the resampling record, so :func:`resampled_band_hz` cannot find the band the models
    know in the file read back, and ``flowtex compare`` grades it up to the Nyquist frequency, where the models hold
    only a stopband ceiling (docs/fitting.md has a measured case).
    """
    top = resampled_band_hz(ms)
    if not math.isfinite(top):
        return None
    return (f"warning: {path}: HaTT XML cannot state that these models were resampled from "
            f"{ms.metadata['resample']['from_hz']:g} Hz; flowtex compare grades the file read back up to "
            f"{ms.sample_rate / 2:g} Hz, above the {top:g} Hz its models know; compare the JSON, which keeps the record")
