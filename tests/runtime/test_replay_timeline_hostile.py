"""A session log's audio timeline is what the replay rebuilds the played stream from: a damaged or forged event (a
size of terabytes, a negative position) is one line naming the log, not numpy's 'Unable to allocate 4.00 TiB' as an
internal error, nor a WAV whose samples a negative index put at the stream's end."""

from __future__ import annotations

import pytest
from long_session import LongSession

from flowtex.errors import DataError
from flowtex.graph.compiled import load_graph
from flowtex.io.canlog import SessionWriter, read_session
from flowtex.runtime.audio_timeline import END, RESYNC, SILENCE, START, event_frame
from flowtex.runtime.replay import replay_session


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    folder = tmp_path_factory.mktemp("timeline")
    s = LongSession(folder, ticks=100)
    s.audio_map()
    return s, list(read_session(s.write(folder / "plain.blf", 60)))


def _replay(session, name, start, after):
    s, frames = session
    log = s.folder / f"{name}.blf"
    w = SessionWriter(log)
    w.write(event_frame(START, *start), False)
    for m in frames:
        w.write(m, m.is_rx)
    for event in after:
        w.write(event_frame(*event), False)
    w.close()
    out = s.folder / f"{name}.wav"
    return log, out, lambda: replay_session(load_graph(s.graph), log, s.dbc, s.folder / "ma.yaml", out, seed=3)


def test_a_consistent_timeline_is_rebuilt(session):
    _log, out, replay = _replay(session, "sane", (100, 16, 80), [(END, 100 + 60 * 8, 60 * 8, 0)])
    assert replay().ticks == 60 and out.is_file()


@pytest.mark.parametrize(("start", "after", "says"), [
    ((100, 16, 80), [(END, 2**40, 480, 0)], "END event: 1,099,511,627,776 frames handed to the sound card"),
    ((100, 16, 80), [(END, -5, 480, 0)], "END event: -5 frames handed to the sound card"),
    ((2**40, 16, 80), [], "START event: a lead of 1,099,511,627,776 frames"),
    ((-50, 16, 80), [(END, 580, 480, 0)], "START event: a lead of -50 frames"),
    ((100, 0, 80), [(END, 580, 480, 0)], "START event: a fade of 0 frames"),
    ((100, 16, 80), [(RESYNC, 5, 2**40, 0)], "RESYNC event: 1,099,511,627,776 frames of silence before tick 5"),
    ((100, 16, 80), [(RESYNC, 5, -1000, 0), (END, 580, 480, 0)], "RESYNC event: -1,000 frames of silence before tick 5"),
    ((100, 16, 80), [(SILENCE, 0, 2**40, 1)], "SILENCE event: frames 0 to 1,099,511,627,776"),
    ((100, 16, 80), [(SILENCE, 50, 10, 1)], "SILENCE event: frames 50 to 10"),
])
def test_a_timeline_event_out_of_bounds_is_one_line_naming_the_log(session, start, after, says):
    log, out, replay = _replay(session, "bad", start, after)
    with pytest.raises(DataError) as info:
        replay()
    msg = str(info.value)
    assert msg.startswith(f"{log}: its audio timeline's {says}") and "\n" not in msg, msg
    assert not out.exists()


def test_a_replayed_stream_longer_than_a_recording_may_be_is_written_block_by_block(session, monkeypatch):
    """The replay rendered every tick's samples whole and refused past MAX_RECORDING_VALUES (17 minutes of 48 kHz
    stereo). It streams now: 300 values stand for 10^8 here, and the 60 ticks (the lead, then 480 frames) are written,
    the lead of silence then the samples one interpolator call gives for the replayed outputs."""
    import numpy as np
    from scipy.io import wavfile

    from flowtex import limits
    from flowtex.dsp.audio_interp import Interpolator
    from flowtex.io.audiomap import load_audio_section
    from flowtex.runtime.audio_render import lead_frames

    s, _frames = session
    out = s.folder / "long.wav"
    replay_session(load_graph(s.graph), s.folder / "plain.blf", s.dbc, s.folder / "ma.yaml", s.folder / "o.npz", seed=3)
    vib = np.load(s.folder / "o.npz")["vibration"].reshape(-1, 1)
    monkeypatch.setattr(limits, "MAX_RECORDING_VALUES", 300)
    assert replay_session(load_graph(s.graph), s.folder / "plain.blf", s.dbc, s.folder / "ma.yaml", out, seed=3).ticks == 60
    lead = lead_frames(load_audio_section(s.folder / "ma.yaml", {"vibration": 1}))
    whole = np.zeros((lead + 480, 1), dtype=np.float32)
    Interpolator(8, 1, np.ones(1), -np.ones(1), np.ones(1)).render(vib, whole[lead:])
    rate, y = wavfile.read(out)
    assert rate == 8000 and np.array_equal(y.reshape(-1, 1), whole)


def test_a_replayed_stream_longer_than_flowtex_renders_is_refused(session, monkeypatch):
    """The bound on a stream's length is one of time now (flowtex.limits.MAX_AUDIO_SECONDS, 10 hours; a session within
    the log limits played at 48 kHz is billions of frames): 0.05 s (400 frames at 8 kHz) stands for it here."""
    from flowtex import limits

    s, _frames = session
    out = s.folder / "refused.wav"
    monkeypatch.setattr(limits, "MAX_AUDIO_SECONDS", 0.05)
    with pytest.raises(DataError) as info:
        replay_session(load_graph(s.graph), s.folder / "plain.blf", s.dbc, s.folder / "ma.yaml", out, seed=3)
    assert str(info.value).startswith(f"{out}: 60 ticks play as ") and "MAX_AUDIO_SECONDS" in str(info.value)
    assert "\n" not in str(info.value) and not out.exists()
