"""The map's ``audio`` section (flowtex.io.audiomap) and WAV files in load/save_recording (flowtex.io.wav)."""

from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
from scipy.io import wavfile

from flowtex.errors import DataError, GraphError
from flowtex.io.audiomap import load_audio_section
from flowtex.io.canmap import load_map
from flowtex.io.dbc import load_dbc
from flowtex.io.recordings import load_recording, save_recording

REPO = Path(__file__).resolve().parents[2]
DBC = REPO / "graphs" / "devices" / "example.dbc"
GOUT = {"vibration": 1, "force": 3}

HEAD = """
flowtex_map: 1
inputs:
  position: {signals: [ToolPosition.PosX, ToolPosition.PosY, ToolPosition.PosZ], timeout_ms: 5}
  normal_force: {signal: NormalForce, timeout_ms: 3}
outputs:
  force: {signals: [ForceCmd.Fx, ForceCmd.Fy, ForceCmd.Fz], clamp: [-4, 4]}
"""


def _load(tmp_path, audio: str):
    p = tmp_path / "m.yaml"
    p.write_text(textwrap.dedent(HEAD).lstrip("\n") + textwrap.dedent(audio))
    return load_map(p, load_dbc(DBC), DBC, {"position": 3, "normal_force": 1}, GOUT)


def test_bundled_example_audio_map():
    m = load_map(REPO / "graphs" / "devices" / "example_audio_map.yaml", load_dbc(DBC), DBC, {"position": 3, "normal_force": 1}, GOUT)
    a = m.audio
    assert (a.rate, a.block, a.device) == (8000.0, 64, None)
    assert [(c.output, c.scale, c.lo, c.hi) for c in a.channels] == [("vibration", 1.5, -1.0, 1.0)]
    assert m.actuator_messages() == ["ForceCmd"]


def test_device_by_name_and_asymmetric_clip(tmp_path):
    a = _load(tmp_path, """
        audio:
          device: "USB Audio"
          rate: 48000
          block: 128
          channels:
            - {output: vibration, scale: 2.0, clip: [-0.5, 1.5]}
        """).audio
    assert a.device == "USB Audio" and a.rate == 48000.0 and (a.channels[0].lo, a.channels[0].hi) == (-0.5, 1.5)


@pytest.mark.parametrize("audio, line, text", [
    ("audio:\n  rate: 8000\n  blok: 64\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 9, "unknown key 'blok' (did you mean 'block'"),
    ("audio:\n  rate: 4000\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 8, "audio.rate must be a number of Hz >= 5000"),
    ("audio:\n  rate: 8000\n  channels: [{output: force, scale: 1, clip: 1}]\n", 9, "output 'force' has 3 components"),
    ("audio:\n  rate: 8000\n  channels: [{output: vibraton, scale: 1, clip: 1}]\n", 9, "no output 'vibraton' (did you mean 'vibration'"),
    ("audio:\n  rate: 8000\n  channels: [{output: vibration, scale: 1}]\n", 9, "clip is required"),
    ("audio:\n  rate: 8000\n  channels: [{output: vibration, scale: 1.0, clip: 1.5}]\n", 9, "exceeds full scale +-1 (scale)"),
    # a clip without 0 played a graph output of 0 (at rest) as a constant offset: 0.5 of full scale, for ever
    ("audio:\n  rate: 8000\n  channels: [{output: vibration, scale: 1.0, clip: [0.5, 1.0]}]\n", 9,
     "clip [0.5, 1] does not contain 0"),
    ("audio:\n  rate: 8000\n  channels: [{output: vibration, scale: 1.0, clip: [-1, -0.25]}]\n", 9,
     "clip [-1, -0.25] does not contain 0"),
    ("audio:\n  rate: 8000\n  block: 0\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 9, "audio.block must be a whole number"),
    ("audio:\n  rate: 8000\n  margin_ms: 0\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 9, "number of ms in (0, 250]"),
    ("audio:\n  rate: 8000\n  margin_ms: 300\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 9, "audio.margin_ms must be"),
    ("audio:\n  rate: 8000\n  margin_ms: ten\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 9, "got 'ten'"),
    ("audio:\n  rate: 8000\n  margin_ms: 20\n  margin_max_ms: 12\n  channels: [{output: vibration, scale: 1, clip: 1}]\n", 10,
     "audio.margin_max_ms (12) is below audio.margin_ms (20)"),
])
def test_errors_name_the_line_and_the_fix(tmp_path, audio, line, text):
    with pytest.raises(GraphError) as err:
        _load(tmp_path, audio)
    msg = str(err.value)
    assert text in msg and f"m.yaml:{line}:" in msg, msg


def test_audio_section_alone_needs_no_dbc(tmp_path):
    a = load_audio_section(REPO / "graphs" / "devices" / "example_audio_map.yaml", GOUT)
    assert a.rate == 8000.0 and a.margin_ms == 10.0 and a.margin_max_ms == 15.0


def test_margin_max_defaults_to_15_ms_or_the_margin_if_larger(tmp_path):
    assert _load(tmp_path, "audio:\n  rate: 8000\n  margin_ms: 0.5\n  channels: [{output: vibration, scale: 1, clip: 1}]\n"
                 ).audio.margin_max_ms == 15.0
    assert _load(tmp_path, "audio:\n  rate: 8000\n  margin_ms: 40\n  channels: [{output: vibration, scale: 1, clip: 1}]\n"
                 ).audio.margin_max_ms == 40.0
    fixed = _load(tmp_path, "audio:\n  rate: 8000\n  margin_ms: 0.5\n  margin_max_ms: 0.5\n"
                  "  channels: [{output: vibration, scale: 1, clip: 1}]\n").audio
    assert (fixed.margin_ms, fixed.margin_max_ms) == (0.5, 0.5)
    with pytest.raises(DataError, match="no 'audio' section"):
        load_audio_section(REPO / "graphs" / "devices" / "example_map.yaml", GOUT)


def test_wav_round_trip_float32_exact_and_pcm16_in_full_scale_units(tmp_path):
    rng = np.random.default_rng(1)
    x = rng.uniform(-1, 1, (500, 2)).astype(np.float32)
    save_recording(tmp_path / "a.wav", {"left": x[:, 0], "right": x[:, 1]}, rate=8000)
    rec = load_recording(tmp_path / "a.wav")
    assert rec.rate == 8000.0 and list(rec.arrays) == ["ch0", "ch1"]
    np.testing.assert_array_equal(rec.arrays["ch0"], x[:, 0].astype(np.float64))
    pcm = (x[:, 0] * 32767).astype(np.int16)
    wavfile.write(tmp_path / "b.wav", 44100, pcm)
    rec = load_recording(tmp_path / "b.wav")
    assert rec.rate == 44100.0
    np.testing.assert_array_equal(rec.arrays["ch0"], pcm / 32768.0)


def test_wav_refuses_what_it_cannot_hold(tmp_path):
    with pytest.raises(DataError, match="whole positive number of Hz"):
        save_recording(tmp_path / "a.wav", {"x": np.zeros(10)}, rate=1000.5)
    with pytest.raises(DataError, match="one scalar signal"):
        save_recording(tmp_path / "a.wav", {"x": np.zeros((10, 3))}, rate=1000)
    (tmp_path / "bad.wav").write_bytes(b"RIFF\x00\x00\x00\x00WAVEjunk")
    with pytest.raises(DataError, match="bad.wav: not a WAV file"):
        load_recording(tmp_path / "bad.wav")
