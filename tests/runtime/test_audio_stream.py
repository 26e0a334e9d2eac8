"""A session's audio is rendered, rebuilt and checked block by block: the same frames, classes and report lines as
the whole arrays gave (tests/runtime/audio_whole.py, the code before), past the old length limit
(MAX_RECORDING_VALUES: 17 minutes of 48 kHz stereo), in memory that does not grow with the stream's length."""

from __future__ import annotations

import numpy as np
import pytest
from audio_whole import check_audio as whole_check
from audio_whole import rebuild_live as whole_rebuild
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from long_session import LongSession, peak_bytes
from scipy.io import wavfile

from flowtex import limits
from flowtex.dsp.audio_interp import Interpolator, frames_before
from flowtex.graph.compiled import load_graph
from flowtex.io.audiomap import default_audio_map
from flowtex.io.canlog import SessionWriter, read_session
from flowtex.io.wav import WavReader, WavWriter
from flowtex.runtime import audio_check, audio_render
from flowtex.runtime.audio_check import AudioChecker, rebuild_blocks
from flowtex.runtime.audio_ring import CLASS_END, CLASS_HELD, CLASS_LATE, CLASS_LEAD
from flowtex.runtime.audio_timeline import END, RESYNC, SILENCE, START, AudioTimeline, event_frame
from flowtex.runtime.replay import replay_session

RATIOS = [(8, 1), (3, 1), (1, 1), (441, 10), (48, 5)]


def _chunks(x: np.ndarray, cuts: list[int]) -> list[np.ndarray]:
    """``x`` split at the (sorted, clipped) row indices ``cuts``."""
    edges = sorted({0, x.shape[0], *(min(c, x.shape[0]) for c in cuts)})
    return [x[a:b] for a, b in zip(edges[:-1], edges[1:], strict=True)]


@st.composite
def streams(draw):
    """A timeline as live writes them (resyncs, silence runs, an END or none) over random tick samples."""
    up, down = draw(st.sampled_from(RATIOS))
    n_ticks = draw(st.integers(0, 30))
    width = draw(st.integers(1, 2))
    n_frames = frames_before(n_ticks, up, down)
    lead, fade = draw(st.integers(0, 40)), draw(st.integers(1, 20))
    resyncs = draw(st.lists(st.tuples(st.integers(0, n_ticks + 2), st.integers(0, 25)), max_size=4))
    span = lead + n_frames + sum(g for _, g in resyncs) + 40
    runs = draw(st.lists(st.tuples(st.integers(0, span), st.integers(0, 40),
                                   st.sampled_from([CLASS_LEAD, CLASS_HELD, CLASS_LATE, CLASS_END])), max_size=5))
    total = draw(st.none() | st.integers(0, span))
    timeline = AudioTimeline(lead=lead, fade=fade, margin=0, resyncs=resyncs,
                             silences=[(a, a + n, r) for a, n, r in runs], total=total)
    rng = np.random.default_rng(draw(st.integers(0, 2**32 - 1)))
    samples = rng.uniform(-1, 1, (n_frames, width)).astype(np.float32)
    cuts = draw(st.lists(st.integers(0, max(n_frames, 1)), max_size=6))
    return up, down, n_ticks, width, timeline, samples, cuts, draw(st.integers(1, 70)), rng


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(streams(), st.integers(-30, 30))
def test_blocks_rebuild_and_check_what_the_whole_arrays_did(case, longer):
    """Any split of the samples, any block size: the frames bit for bit, the classes, and the report lines of a live
    stream that differs here and there (and is longer or shorter) are the whole-array code's."""
    up, down, n_ticks, width, timeline, samples, cuts, block, rng = case
    old_out, old_klass = whole_rebuild(samples, n_ticks, up, down, timeline)
    blocks = list(rebuild_blocks(_chunks(samples, cuts), n_ticks, up, down, timeline, width, block))
    assert all(o.shape[0] == block for o, _ in blocks[:-1])
    out = np.concatenate([o for o, _ in blocks]) if blocks else np.zeros((0, width), np.float32)
    klass = np.concatenate([k for _, k in blocks]) if blocks else np.zeros(0, np.uint8)
    assert out.dtype == np.float32 and out.tobytes() == old_out.tobytes() and np.array_equal(klass, old_klass)

    live = np.zeros((max(1, old_out.shape[0] + longer), width))  # a WAV has a frame at least (read_wav, WavReader)
    n = min(live.shape[0], old_out.shape[0])
    live[:n] = old_out[:n]
    if n:
        live[rng.integers(0, n, 3)] += 0.25  # three frames that differ (or fewer when they coincide)
    checker = AudioChecker(timeline, "live.wav", 8000.0)
    at = 0
    for o, k in blocks:
        checker.feed(live[at:at + o.shape[0]], o, k)
        at += o.shape[0]
    new = checker.finish(live.shape[0], out.shape[0])
    old = whole_check(live, old_out, old_klass, timeline, "live.wav", 8000.0)
    assert new.lines == old.lines and new.unexplained == old.unexplained


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    """A 60-tick session log with a timeline: the lead, a 30-frame resync before tick 5, the fade at the end."""
    folder = tmp_path_factory.mktemp("audiostream")
    s = LongSession(folder, ticks=100)
    s.audio_map()
    frames = list(read_session(s.write(folder / "plain.blf", 60)))
    log = folder / "timeline.blf"
    w = SessionWriter(log)
    w.write(event_frame(START, 100, 16, 80), False)
    for m in frames:
        w.write(m, m.is_rx)
    for event in [(RESYNC, 5, 30, 170), (SILENCE, 0, 100, CLASS_LEAD), (SILENCE, 140, 170, CLASS_LATE),
                  (SILENCE, 610, 640, CLASS_END), (END, 640, 480, 0)]:
        w.write(event_frame(*event), False)
    w.close()
    replay_session(load_graph(s.graph), log, s.dbc, folder / "ma.yaml", folder / "o.npz", seed=3)
    vib = np.load(folder / "o.npz")["vibration"].reshape(-1, 1)
    samples = np.zeros((480, 1), dtype=np.float32)
    Interpolator(8, 1, np.ones(1), -np.ones(1), np.ones(1)).render(vib, samples)  # the map: scale 1, clip 1
    return s, log, samples


def test_expect_audio_past_the_old_limit_reports_what_the_whole_arrays_did(session, monkeypatch):
    """The replay's WAV and --expect-audio of a stream of 640 frames with 300 values standing for 10^8 (which refused
    both before), 3 ticks rendered and 37 frames compared a block: the WAV is the whole-array rebuild bit for bit, and
    the report of a live WAV with one frame off is the whole-array check's, line for line."""
    s, log, samples = session
    timeline = AudioTimeline(lead=100, fade=16, margin=80, resyncs=[(5, 30)],
                             silences=[(0, 100, CLASS_LEAD), (140, 170, CLASS_LATE), (610, 640, CLASS_END)], total=640)
    expected, klass = whole_rebuild(samples, 60, 8, 1, timeline)
    monkeypatch.setattr(limits, "MAX_RECORDING_VALUES", 300)
    monkeypatch.setattr(audio_render, "BLOCK_TICKS", 3)
    monkeypatch.setattr(audio_check, "BLOCK_FRAMES", 37)
    out = s.folder / "replay.wav"
    replay_session(load_graph(s.graph), log, s.dbc, s.folder / "ma.yaml", out, seed=3)
    rate, y = wavfile.read(out)  # read_wav is held to the lowered limit
    assert rate == 8000 and y.tobytes() == expected.tobytes()

    live = expected.copy()
    live[300, 0] = np.float32(0.125) if live[300, 0] != np.float32(0.125) else np.float32(0.25)
    w = WavWriter(s.folder / "live.wav", 8000, 1)
    w.write(live)
    w.close()
    report = replay_session(load_graph(s.graph), log, s.dbc, s.folder / "ma.yaml", seed=3, expect_audio=s.folder / "live.wav")
    old = whole_check(live.astype(np.float64), expected, klass, timeline, str(s.folder / "live.wav"), 8000.0)
    assert report.audio_lines == old.lines and report.audio_unexplained == old.unexplained == 1
    assert "1 frames DIFFER (the ticks' samples), first at frame 300" in "\n".join(report.audio_lines)


def _design_peak(width: int) -> int:
    """Peak bytes of designing the interpolation filter (scipy, ~3.7 MB at 8x), which every render does once whatever
    its length: the part of a render's peak that is not its blocks."""
    amap = default_audio_map({f"c{i}": 1 for i in range(width)}, 8000.0)
    audio_render.interpolator(amap, (8, 1))  # imports and caches first
    return peak_bytes(lambda: audio_render.interpolator(amap, (8, 1)))


def _stream_peak(tmp_path, ticks: int, monkeypatch) -> tuple[int, int]:
    """Peak bytes allocated rendering ``ticks`` ticks at 8x, rebuilding the stream of a timeline with a resync and a
    fade, writing it and checking it against a live WAV (the stream itself), block by block; and the stream's bytes."""
    monkeypatch.setattr(audio_render, "BLOCK_TICKS", 1024)
    monkeypatch.setattr(audio_check, "BLOCK_FRAMES", 8192)
    amap = default_audio_map({"a": 1, "b": 1}, 8000.0)
    t = np.arange(ticks) / 1000.0
    outputs = {"a": 0.5 * np.sin(2 * np.pi * 7 * t), "b": 0.25 * np.cos(2 * np.pi * 3 * t)}
    timeline = AudioTimeline(lead=100, fade=16, margin=80, resyncs=[(ticks // 2, 40)],
                             silences=[(0, 100, CLASS_LEAD)], total=None)

    def stream():
        return rebuild_blocks(audio_render.render_blocks(outputs, amap, 1000.0), ticks, 8, 1, timeline, 2)

    w = WavWriter(tmp_path / f"live{ticks}.wav", 8000, 2)
    for block, _ in stream():
        w.write(block)
    w.close()
    reader = WavReader(tmp_path / f"live{ticks}.wav")

    def check():
        writer = WavWriter(tmp_path / f"replay{ticks}.wav", 8000, 2)
        checker = AudioChecker(timeline, "live.wav", 8000.0)
        for block, klass in stream():
            writer.write(block)
            checker.feed(reader.read(block.shape[0]), block, klass)
        writer.close()
        result = checker.finish(reader.frames, reader.frames)
        assert result.unexplained == 0 and result.lines[0].startswith(f"audio: {reader.frames} frames compared")

    peak = peak_bytes(check)
    reader.close()
    return peak, reader.frames * 2 * 4


def test_memory_of_a_streamed_render_and_check_does_not_grow_with_the_stream(tmp_path, monkeypatch):
    """4x the ticks (1.28 M frames x 2 channels: 10 MB as float32, 20 MB as the float64 the check compares): the peak
    stays that of a block (8,192 frames and 1,024 ticks here, ~0.5 MB with their float64 copies and masks; 65,536 and
    4,096 by default). The whole-array code held the whole stream, and more (the live WAV in float64, the rebuilt
    stream, its classes)."""
    small, _ = _stream_peak(tmp_path, 40_000, monkeypatch)
    large, stream_bytes = _stream_peak(tmp_path, 160_000, monkeypatch)
    assert large < 1.25 * small, (small, large)  # flat: the blocks are the same size; 25 % for allocator noise
    assert large - _design_peak(2) < stream_bytes / 8, (large, stream_bytes)


def test_memory_of_an_offline_render_does_not_grow_with_the_stream(tmp_path, monkeypatch):
    """``run --output OUT.wav``'s writer (audio_render.write_render, with the clip count): the peak at 4x the ticks is
    the peak at 1x, and far below the stream it writes (1,024 ticks a block here)."""
    monkeypatch.setattr(audio_render, "BLOCK_TICKS", 1024)
    amap = default_audio_map({"a": 1}, 8000.0)

    def peak(ticks: int) -> int:
        outputs = {"a": np.sin(np.arange(ticks) / 50.0)}
        return peak_bytes(lambda: (audio_render.write_render(tmp_path / f"r{ticks}.wav", outputs, amap, 1000.0),
                                   audio_render.clip_shares(outputs, amap, 1000.0)))

    small, large = peak(40_000), peak(160_000)
    assert large < 1.25 * small, (small, large)  # flat, as above
    assert large - _design_peak(1) < 160_000 * 8 * 4 / 8, large  # an eighth of the 5 MB stream


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(RATIOS), st.integers(1, 25), st.integers(0, 40), st.integers(1, 20), st.integers(-60, 60),
       st.integers(1, 50), st.integers(0, 2**32 - 1), st.integers(0, 4))
def test_blocks_compare_a_log_without_timeline_as_the_whole_arrays_did(ratio, n_ticks, lead, fade, longer, block, seed,
                                                                        changes):
    """A log recorded before the timeline: the live WAV is the replay with fades where live had no tick (a stall, the
    end) and a few frames off; AudioComparer over blocks of any size counts what compare_audio counts on whole arrays."""
    from flowtex.runtime.audio_check import AudioComparer, compare_audio, fade_from, known_end

    up, down = ratio
    rng = np.random.default_rng(seed)
    replay = np.zeros((lead + frames_before(n_ticks, up, down), 1), dtype=np.float32)
    replay[lead:] = rng.uniform(-1, 1, (replay.shape[0] - lead, 1)).astype(np.float32)
    live = np.zeros((max(1, replay.shape[0] + longer), 1))
    n = min(live.shape[0], replay.shape[0])
    live[:n] = replay[:n]
    for _ in range(changes):  # a fade in place of some frames (safe silence), or a frame off (unexplained)
        a = int(rng.integers(0, live.shape[0]))
        b = min(live.shape[0], a + int(rng.integers(1, 30)))
        live[a:b] = fade_from(live[a - 1] if a else np.zeros(1), b - a, fade) if rng.random() < 0.6 else live[a:b] + 0.5
    if live.shape[0] > n:
        live[n:] = fade_from(live[n - 1] if n else np.zeros(1), live.shape[0] - n, fade)
    old = compare_audio(live, replay, lead, up, [], fade, down)
    cmp = AudioComparer(known_end(live.shape[0], n_ticks, lead, up, down), lead, fade, 1)
    for a in range(0, live.shape[0], block):
        cmp.feed(live[a:a + block], replay[a:a + block])
    assert cmp.finish() == old


def test_expect_audio_of_a_log_without_timeline_past_the_old_limit(session, monkeypatch):
    """A log recorded before the timeline (plain.blf): its replay WAV and --expect-audio stream too (300 values stand for
    10^8, 37 frames a block): the report of a live WAV with one frame off and a longer tail of fade is compare_audio's on
    the whole arrays."""
    from flowtex.runtime.audio_check import compare_audio, fade_from

    s, _log, samples = session
    monkeypatch.setattr(limits, "MAX_RECORDING_VALUES", 300)
    monkeypatch.setattr(audio_render, "BLOCK_TICKS", 3)
    monkeypatch.setattr(audio_check, "BLOCK_FRAMES", 37)
    out = s.folder / "plain_replay.wav"
    replay_session(load_graph(s.graph), s.folder / "plain.blf", s.dbc, s.folder / "ma.yaml", out, seed=3)
    rate, replay = wavfile.read(out)
    lead = replay.shape[0] - 480
    assert rate == 8000 and replay[:lead].tobytes() == bytes(4 * lead) and replay[lead:].tobytes() == samples.tobytes()
    live = np.concatenate([replay, fade_from(replay[-1:], 40, 16)[:, 0].astype(np.float32)]).reshape(-1, 1)
    live[lead + 200, 0] += np.float32(0.125)
    w = WavWriter(s.folder / "plain_live.wav", 8000, 1)
    w.write(live)
    w.close()
    report = replay_session(load_graph(s.graph), s.folder / "plain.blf", s.dbc, s.folder / "ma.yaml", seed=3,
                            expect_audio=s.folder / "plain_live.wav")
    old = compare_audio(live.astype(np.float64), replay, lead, 8, [], 16, 1)
    assert old.unexplained == 1 and old.silence == lead + 40 and old.first_unexplained == lead + 200  # the lead: zeros
    name = str(s.folder / "plain_live.wav")
    assert report.audio_lines == [
        f"audio: the session log holds no audio timeline (recorded before flowtex logged it): {name} checked where live "
        "played a tick",
        f"{old.equal} frames: the ticks' samples, equal to {name} sample for sample",
        f"{old.silence} frames: the callback's fade to silence (where live had no tick to play)",
        f"1 frames DIFFER, first at frame {lead + 200}: unexplained"]
