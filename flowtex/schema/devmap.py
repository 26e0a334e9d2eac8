"""The device map file with its audio section (docs/live.md), declared once: :mod:`flowtex.io.canmap` and
:mod:`flowtex.io.audiomap` check with it, editors get its JSON Schema. Checks against the DBC and the graph
(signal names, ranges, widths) stay in those loaders: they need the device and the graph."""

from __future__ import annotations

from .core import Field, Record

DEFAULT_OVERRUN_MS = 2.0
MAX_MAP_MS = 86_400_000.0
"""Longest ``timeout_ms``, ``overrun_limit_ms`` and peak ``max_ms`` (one day): longer is no watchdog, and a
duration past ~2^63 ns would not even fit the watchdog's integer nanoseconds and ticks."""
PEAK_RECOVER_RATIO = 60
"""Default peak ``recover_ms`` per ms of ``max_ms``: an empty allowance refills in 60 times its length, so over any long
run at most 1/61 of the ticks exceed the clamp, the duty of IEC 60268-5's short-term test of a loudspeaker (1 s of
signal, 60 s of rest; docs/live.md, "Peak rule")."""
MIN_AUDIO_RATE = 5000.0
"""Lowest audio rate accepted, Hz (the issue's and Culbertson 2012's floor)."""
DEFAULT_AUDIO_MARGIN_MS = 10.0
"""Default ``audio.margin_ms``: a stall of the tick loop shorter than this costs no sample (docs/live.md, "Audio output")."""
MAX_AUDIO_MARGIN_MS = 250.0
"""Largest ``audio.margin_ms``: every millisecond of margin is a millisecond of sensor-to-sound latency."""
DEFAULT_AUDIO_MARGIN_MAX_MS = 15.0
"""Default ``audio.margin_max_ms`` (or ``margin_ms`` if larger): how far the margin may grow after stalls it did not absorb;
at 8 kHz / 64 under JACK (3 blocks, 24 ms) it keeps sensor-to-sound latency within 40 ms."""
SIGNAL_PATTERN = r"^[^.\s]+\.[^.\s]+$"

_NUMBER = Field("number")
PER_COMPONENT = Field("any_of", of=(_NUMBER, Field("list", items=_NUMBER, length=(1, None))),
                      message="{what}: '{key}' must be a number or a list of {width} numbers, got {got}")
"""A number for every component, or one number per component."""
_PAIR = Field("list", items=_NUMBER, length=(2, 2))

_SIGNALS = {
    "signal": Field("str", pattern=SIGNAL_PATTERN, doc="The DBC signal, MESSAGE.SIGNAL (a scalar port)."),
    "signals": Field("list", items=Field("str", pattern=SIGNAL_PATTERN), length=(1, None),
                     doc="One DBC signal per component, MESSAGE.SIGNAL, in C order over the port's shape."),
}


def _linear(doc: str) -> dict[str, Field]:
    """``scale`` and ``offset`` of a binding (per component or one for all), documented by ``doc``."""
    return {key: Field("any_of", of=PER_COMPONENT.of, default=default, doc=doc, message=PER_COMPONENT.message)
            for key, default in (("scale", 1.0), ("offset", 0.0))}


_ONE_SIGNAL_KEY = {"oneOf": [{"required": ["signal"]}, {"required": ["signals"]}]}

INPUT_BINDING = Record(
    keys={
        **_SIGNALS,
        **_linear("graph value = DBC physical value * scale + offset."),
        "timeout_ms": Field("number", unit="ms", min=0.0, min_exclusive=True, max=MAX_MAP_MS,
                            doc="How old a sensor value may get before the watchdog sends safe outputs.",
                            message=f"{{what}}: timeout_ms must be a positive number of milliseconds, at most {MAX_MAP_MS:.0f} "
                                    "(one day), got {got}",
                            missing="{what}: missing 'timeout_ms' (how old, in ms, a sensor value may get before outputs go safe)"),
        "doc": Field("str", doc="Free text."),
    },
    required=("timeout_ms",),
    unknown="{what}: unknown key {name!r}{hint}",
    suggest="close_or_known",
    json=_ONE_SIGNAL_KEY,
    doc="A graph input read from DBC signals.",
)

PEAK = Record(
    keys={
        "limit": Field("any_of", of=PER_COMPONENT.of, doc="|value| allowed above the clamp, graph units, for at most max_ms."),
        "max_ms": Field("number", unit="ms", min=0.0, max=MAX_MAP_MS, doc="How long the peak may last (the allowance, when full).",
                        message=f"{{what}}: peak max_ms must be a non-negative number of milliseconds, at most {MAX_MAP_MS:.0f} "
                                "(one day), got {got}"),
        "recover_ms": Field("number", unit="ms", min=0.0, min_exclusive=True, max=MAX_MAP_MS,
                            doc="Time within the clamp that refills an empty allowance (gradually: max_ms/recover_ms of a "
                                f"tick per tick); absent: {PEAK_RECOVER_RATIO} x max_ms. At most max_ms/(max_ms + recover_ms) "
                                "of any long run exceeds the clamp.",
                            message=f"{{what}}: peak recover_ms must be a positive number of milliseconds, at most {MAX_MAP_MS:.0f} "
                                    "(one day), got {got}"),
    },
    required=("limit", "max_ms"),
    doc="A short excursion above the clamp, with an allowance that refills over time.",
)

OUTPUT_BINDING = Record(
    keys={
        **_SIGNALS,
        **_linear("DBC physical value = graph value * scale + offset."),
        "clamp": Field("any_of", of=(_PAIR, Field("list", items=_PAIR, length=(1, None))),
                       doc="[LOW, HIGH] in graph units the actuator may be commanded (or one pair per component).",
                       missing="{what}: missing 'clamp: [LOW, HIGH]' (the range, in graph units, the actuator may be commanded)"),
        "safe": Field("any_of", of=PER_COMPONENT.of, default=0.0, doc="Value sent when the watchdog trips and on exit, graph units.",
                      message=PER_COMPONENT.message),
        "peak": Field("record", record=PEAK, doc=PEAK.doc,
                      message="{what}: peak must be {{limit: L, max_ms: D}} or {{limit: L, max_ms: D, recover_ms: T}} "
                              "(allow |value| up to L for at most D ms, refilled over T ms within the clamp)"),
        "doc": Field("str", doc="Free text."),
    },
    required=("clamp",),
    unknown="{what}: unknown key {name!r}{hint}",
    suggest="close_or_known",
    json=_ONE_SIGNAL_KEY,
    doc="A graph output sent in DBC signals.",
)

CHANNEL = Record(
    keys={
        "output": Field("str", doc="A scalar graph output.", message="audio.channels[{i}]: 'output' must name a scalar graph output"),
        "scale": Field("number", default=1.0, min=0.0, min_exclusive=True, doc="Graph units per full-scale sample (sample = value / scale).",
                       message="audio.channels[{i}]: scale must be a positive number of graph units per full-scale sample, got {got}"),
        "clip": Field("any_of", of=(Field("number", min=0.0, min_exclusive=True), _PAIR),
                      doc="Graph units: a number C means [-C, C]; or [LOW, HIGH] with LOW <= 0 <= HIGH (0 plays as silence).",
                      message="audio.channels[{i}]: clip is required: a number C (clip to [-C, C]) or [LOW, HIGH] in graph units, got {got}"),
        "doc": Field("str", doc="Free text."),
    },
    required=("output", "clip"),
    unknown="audio.channels[{i}]: unknown key {name!r}{hint}",
    suggest="close_or_known",
    doc="One audio channel.",
)

AUDIO = Record(
    keys={
        "device": Field("any_of", of=(Field("str"), Field("int"), Field("const", const=None)),
                        doc="PortAudio device name (substring) or index; absent: the default output.",
                        message="audio.device must be a device name or index (flowtex live --list-audio), got {got}"),
        "rate": Field("number", unit="Hz", min=MIN_AUDIO_RATE,
                      doc="Audio rate, p/q times the graph's rate (p, q <= 1000: 8000, 44100, 48000 for a 1 kHz graph).",
                      message=f"audio.rate must be a number of Hz >= {MIN_AUDIO_RATE:g} (e.g. 8000 or 48000), got {{got}}"),
        "block": Field("int", default=64, min=1, max=65536, doc="Frames per PortAudio callback.",
                       message="audio.block must be a whole number of frames per callback (e.g. 64), got {got}"),
        "margin_ms": Field("number", unit="ms", default=DEFAULT_AUDIO_MARGIN_MS, min=0.0, min_exclusive=True,
                           max=MAX_AUDIO_MARGIN_MS,
                           doc="How far ahead of the sound card the ticks run: a stall of the tick loop shorter than this "
                               "costs no sample; sensor-to-sound latency grows by as much.",
                           message=f"audio.margin_ms must be a number of ms in (0, {MAX_AUDIO_MARGIN_MS:g}] (default "
                                   f"{DEFAULT_AUDIO_MARGIN_MS:g}: robust without --rt; e.g. 0.5 with --rt for low latency), "
                                   "got {got}"),
        "margin_max_ms": Field("number", unit="ms", default=DEFAULT_AUDIO_MARGIN_MAX_MS, min=0.0, min_exclusive=True,
                               max=MAX_AUDIO_MARGIN_MS,
                               doc="How far the margin may grow: a stall longer than the margin inserts silence once and "
                                   "raises the margin to absorb as long a stall next time, up to this; absent: "
                                   f"{DEFAULT_AUDIO_MARGIN_MAX_MS:g} or margin_ms if larger; equal to margin_ms: fixed margin.",
                               message=f"audio.margin_max_ms must be a number of ms in (0, {MAX_AUDIO_MARGIN_MS:g}], at least "
                                       "margin_ms (equal: the margin never grows), got {got}"),
        "channels": Field("list", items=Field("record", record=CHANNEL), length=(1, None), doc="One entry per audio channel, in order.",
                          message="audio.channels must be a list of {{output: NAME, scale: S, clip: C}}, one per channel"),
        "doc": Field("str", doc="Free text."),
    },
    required=("rate", "channels"),
    unknown="audio: unknown key {name!r}{hint}",
    suggest="close_or_known",
    doc="Graph outputs played through the sound card.",
)

MAP = Record(
    keys={
        "flowtex_map": Field("const", const=1, default=1, doc="The map format version.",
                             message="unsupported map format version {got} (this flowtex reads version 1)"),
        "description": Field("any", doc="Free text."),
        "overrun_limit_ms": Field("number", unit="ms", min=0.0, min_exclusive=True, max=MAX_MAP_MS, default=DEFAULT_OVERRUN_MS,
                                  doc="A tick this late forces safe values.",
                                  message=f"overrun_limit_ms must be a positive number of milliseconds, at most {MAX_MAP_MS:.0f} "
                                          "(one day), got {got}"),
        "inputs": Field("map", values=Field("record", record=INPUT_BINDING), doc="Graph input name -> the DBC signals it reads.",
                        missing="missing 'inputs:' section (a mapping from graph input names to signals)",
                        message="'inputs' must be a mapping from graph input names to bindings"),
        "outputs": Field("map", values=Field("record", record=OUTPUT_BINDING), doc="Graph output name -> the DBC signals it drives.",
                         missing="missing 'outputs:' section (a mapping from graph output names to signals)",
                         message="'outputs' must be a mapping from graph output names to bindings"),
        "audio": Field("record", record=AUDIO, doc=AUDIO.doc,
                       message="'audio' must be a mapping with keys rate, block, channels (and optional device)"),
    },
    required=("inputs", "outputs"),
    unknown="unknown key {name!r}{hint}",
    suggest="close_or_known",
    doc="A flowtex device map: which DBC signals feed which graph inputs, which graph outputs drive which signals.",
)
