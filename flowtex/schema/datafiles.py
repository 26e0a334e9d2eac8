"""flowtex's JSON data files, declared once: native texture model set (docs/model-sets.md), pattern file
(docs/pattern-format.md), tap library (docs/tap-library.md) and friction estimate (docs/friction.md).

Their readers (:mod:`flowtex.io.modelset`, :mod:`flowtex.io.patternfile`, :mod:`flowtex.io.taplib`,
:mod:`flowtex.filecheck`) check keys and values with these records; numerical checks (stability, triangulation) stay
in the readers. Every file spells its rate ``sample_rate`` (Hz); ``sample_rate_hz``, which tap libraries and pattern
files used to write, is still read. To extend a format, add keys here.
"""

from __future__ import annotations

from ..models.outside import OUTSIDE_CHOICES
from ..models.rendering import INTERPOLATION_CHOICES
from .core import Field, Record

RATE_KEY = "sample_rate"
OLD_RATE_KEY = "sample_rate_hz"

_NUM = Field("number")
_NUMS = Field("list", items=_NUM)


def _format(name: str) -> Field:
    return Field("const", const=name, doc=f"Always {name!r}.")


def _version() -> Field:
    return Field("const", const=1, doc="The format version.")


_RATE = Field("number", unit="Hz", min=0.0, min_exclusive=True, doc="The rate the data were sampled at.")

MODEL = Record(
    keys={
        "speed": Field("number", unit="mm/s", doc="Scan speed of the model."),
        "force": Field("number", unit="N", doc="Normal force of the model."),
        "ar_lsf": Field("list", items=_NUM, doc="AR line spectral frequencies (ar_order values)."),
        "ma_lsf": Field("list", items=_NUM, doc="MA line spectral frequencies (ma_order values)."),
        "variance": Field("number", unit="(m/s^2)^2", doc="Excitation variance."),
        "gain": Field("number", doc="MA gain."),
        "ar_coeff": Field("list", items=_NUM, doc="AR polynomial (ar_order + 1 values), optional."),
        "ma_coeff": Field("list", items=_NUM, doc="MA polynomial (ma_order + 1 values), optional."),
    },
    required=("speed", "force", "ar_lsf", "ma_lsf", "variance", "gain"),
    doc="One texture model at one (speed, force).",
)

MODEL_SET = Record(
    keys={
        "format": _format("flowtex-texture-models"),
        "version": _version(),
        "material": Field("str", doc="Name of the material."),
        RATE_KEY: _RATE,
        "mu": Field("any_of", of=(Field("number"), Field("const", const=None)), doc="Kinetic friction coefficient, or null."),
        "max_speed": Field("number", unit="mm/s", doc="Largest speed rendered (default: the largest model speed)."),
        "max_force": Field("number", unit="N", doc="Largest force rendered (default: the largest model force)."),
        "interpolation": Field("choice", choices=INTERPOLATION_CHOICES,
                               doc="How loudness is blended between models (docs/texture.md); absent: HaTT's, variance."),
        "outside": Field("choice", choices=OUTSIDE_CHOICES,
                         doc="What the set renders beyond its measured models (docs/texture.md); absent: HaTT's, fade."),
        "ar_order": Field("int", min=0, max=1000, doc="AR order."),
        "ma_order": Field("int", min=0, max=1000, doc="MA order."),
        "triangles": Field("list", items=Field("list", items=Field("int", min=0), length=(3, 3)),
                           doc="0-based model indices of each triangle; absent: Delaunay at load time."),
        "models": Field("list", items=Field("record", record=MODEL), length=(1, None), doc="The models."),
        "metadata": Field("map", doc="Free-form."),
    },
    required=("format", "version", "material", RATE_KEY, "ar_order", "ma_order", "models"),
    legacy={OLD_RATE_KEY: RATE_KEY},
    unknown="unknown top-level key {key}{hint}; a model set has {allowed}",
    doc="A flowtex texture model set.",
)

FEATURE = Record(
    keys={
        "position_mm": Field("number", unit="mm", doc="Position of the feature along the axis."),
        "amplitude": Field("number", unit="m/s^2", doc="Amplitude A_k."),
        "b": Field("list", items=_NUM, length=(1, 33), doc="Numerator of the feature's filter."),
        "a": Field("list", items=_NUM, length=(1, 33), doc="Denominator of the feature's filter (a[0] = 1)."),
    },
    required=("position_mm", "amplitude", "b", "a"),
    unknown="{where}: unknown key {key}{hint}; a feature has {allowed}",
    doc="One feature of a patterned texture.",
)

PATTERN = Record(
    keys={
        "format": _format("flowtex-pattern"),
        "version": _version(),
        RATE_KEY: _RATE,
        "axis": Field("list", items=_NUM, length=(3, 3), doc="Direction of the pattern's axis."),
        "origin_mm": Field("list", items=_NUM, length=(3, 3), unit="mm", doc="Origin of the axis."),
        "features": Field("list", items=Field("record", record=FEATURE), length=(1, None), doc="The features."),
        "metadata": Field("map", doc="Free-form."),
    },
    required=("format", "version", RATE_KEY, "axis", "origin_mm", "features"),
    legacy={OLD_RATE_KEY: RATE_KEY},
    unknown="unknown key {key}{hint}; a pattern file has {allowed}",
    doc="A flowtex pattern file: features along a straight axis and their IIR filters.",
)

TAP = Record(
    keys={"speed": Field("number", unit="mm/s", min=0.0, min_exclusive=True, doc="Incoming speed of the tap."),
          "acceleration": Field("list", items=_NUM, length=(1, None), unit="m/s^2", doc="The recorded transient.")},
    required=("speed", "acceleration"),
    unknown="field '{where}.{name}' is unknown{hint}; a tap has 'speed' and 'acceleration'",
    missing="field '{where}.{name}' is missing",
    doc="One recorded tap transient.",
)

TAP_LIBRARY = Record(
    keys={
        "format": _format("flowtex-tap-library"),
        "version": _version(),
        "name": Field("str", doc="Name of the library (default: the file name)."),
        "notes": Field("any", doc="Free text."),
        RATE_KEY: Field("number", unit="Hz", doc="The rate the transients were sampled at.",
                        missing=f"missing field {RATE_KEY!r} (the rate the transients were sampled at, Hz; older files: {OLD_RATE_KEY!r})"),
        "speed_unit": Field("const", const="mm/s", doc="Always 'mm/s'."),
        "acceleration_unit": Field("const", const="m/s^2", doc="Always 'm/s^2'."),
        "taps": Field("list", items=Field("record", record=TAP), length=(1, None), doc="The taps."),
    },
    required=("format", "version", RATE_KEY, "taps"),
    legacy={OLD_RATE_KEY: RATE_KEY},
    unknown="unknown field {name!r}{hint}; allowed: {allowed}",
    doc="A flowtex tap library.",
)

FRICTION = Record(
    keys={
        "format": _format("flowtex-friction"),
        "version": _version(),
        "mu": Field("number", min=0.0, doc="Kinetic friction coefficient.", message="key 'mu' must be a number from 0 to inf, got {got}",
                    missing="key 'mu' must be a number from 0 to inf, got None"),
        "mu_ci": Field("list", items=_NUM, length=(2, 2), doc="95 % interval of mu.",
                       message="key 'mu_ci' must be [low, high] (the 95 % interval of mu)",
                       missing="key 'mu_ci' must be [low, high] (the 95 % interval of mu)"),
    },
    required=("format", "version", "mu", "mu_ci"),
    open=True,  # fit friction also records its inputs and fit statistics
    doc="A flowtex friction estimate (flowtex fit friction).",
)
