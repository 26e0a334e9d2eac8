"""A sound device that cannot play the map's audio rate: the one-line refusal names the device's rate and the map line.

A sound server (JACK at 48 kHz, a USB card) refuses a stream at any other rate; PortAudio says only "Invalid sample
rate". PortAudio is replaced by a stand-in that refuses as it does, so the message is checked without a server
(tests/runtime/test_audio_jack.py runs the real one).
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from flowtex.graph.compiled import load_graph
from flowtex.io.audiomap import load_audio_section
from flowtex.runtime import audio
from flowtex.runtime.audio import AudioDeviceError, AudioOutput

REPO = Path(__file__).resolve().parents[2]
MAP = REPO / "graphs" / "devices" / "example_audio_map.yaml"


class _PortAudioError(Exception):
    pass


def _portaudio(native_rate: float) -> SimpleNamespace:
    """What sounddevice offers here: a stream that refuses the rate, and the device's own rate."""
    def refuse(**kwargs):
        raise _PortAudioError("Error opening OutputStream: Invalid sample rate [PaErrorCode -9997]")
    return SimpleNamespace(PortAudioError=_PortAudioError, OutputStream=refuse,
                           query_devices=lambda device, kind: {"name": "system", "default_samplerate": native_rate})


def _output(tmp_path: Path) -> AudioOutput:
    (tmp_path / "g.yaml").write_text("flowtex: 1\nname: vib\nrate: 1000\ninputs:\n  x: {}\nnodes:\n  v: {type: gain, params: {k: 0.5}}\n"
                                     "edges:\n  - x -> v.x\noutputs:\n  vibration: v.y\n")
    return AudioOutput(load_graph(tmp_path / "g.yaml").with_block_rows(1), load_audio_section(MAP, {"vibration": 1}))


def test_a_device_at_another_rate_is_named_with_the_maps_line(tmp_path, monkeypatch):
    monkeypatch.setattr(audio, "_sd", lambda: _portaudio(48000.0))
    line = next(i for i, text in enumerate(MAP.read_text().splitlines(), 1) if text.lstrip().startswith("rate:"))
    with pytest.raises(AudioDeviceError) as e:
        _output(tmp_path).start()
    msg = str(e.value)
    assert "\n" not in msg and msg.startswith("audio device default output: cannot open 1 channel(s) at 8000 Hz"), msg
    assert f"; the device runs at 48000 Hz: set audio.rate: 48000 ({MAP}:{line}:" in msg, msg
    assert len(f"tick 0: {msg} (safe values sent)") <= 300, msg  # live shows an error up to 300 characters


def test_a_device_at_the_maps_rate_gets_no_rate_hint(tmp_path, monkeypatch):
    monkeypatch.setattr(audio, "_sd", lambda: _portaudio(8000.0))  # refused for another reason: no rate to suggest
    with pytest.raises(AudioDeviceError) as e:
        _output(tmp_path).start()
    assert "runs at" not in str(e.value) and "Invalid sample rate" in str(e.value)
