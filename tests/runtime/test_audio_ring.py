"""The tick loop -> audio callback hand-over (flowtex.runtime.audio_ring) and the live/replay check, without a device."""

from __future__ import annotations

import numpy as np

from flowtex.runtime.audio_check import compare_audio, fade_from
from flowtex.runtime.audio_ring import LATENCIES, MISSING, PLAYED, RECORDED, STOPPING, UNDERRUNS, AudioRing

UP, LEAD, RATE = 8, 80, 8000


def _ring() -> AudioRing:
    return AudioRing(UP, 1, LEAD, RATE, record_s=1.0)


def _callback(ring: AudioRing, frames: int, dac_ns: int = 0) -> np.ndarray:
    out = np.zeros((frames, 1), dtype=np.float32)
    ring.fill(out, dac_ns)
    return out[:, 0]


def _block(k: int) -> np.ndarray:
    return np.full((UP, 1), 0.1 + 0.01 * k, dtype=np.float32)


def test_ticks_play_at_their_positions_after_the_lead():
    ring = _ring()
    for k in range(20):
        ring.put(k, _block(k), arrival_ns=1000 + k, silent=False)
    out = _callback(ring, 64)
    out = np.concatenate([out, _callback(ring, 64)])
    assert not out[:LEAD].any()  # silence at stream start
    np.testing.assert_array_equal(out[LEAD:LEAD + UP], np.float32(0.1))
    np.testing.assert_array_equal(out[LEAD + UP:LEAD + 2 * UP], np.float32(0.11))
    assert ring.istate[PLAYED] == 128 - LEAD and ring.istate[MISSING] == 0 and ring.istate[UNDERRUNS] == 0
    assert ring.istate[LATENCIES] == (128 - LEAD) // UP  # one latency sample per tick that started here
    np.testing.assert_array_equal(ring.drain()[1][:, 0], out)  # the recording is exactly what was handed over


def test_missing_and_silent_ticks_fade_to_zero_within_the_fade_and_only_late_ones_count():
    ring = _ring()
    for k in range(4):
        ring.put(k, _block(k), 0, silent=False)
    ring.put(4, _block(4), 0, silent=True)  # the watchdog held tick 4: safe silence, not an underrun
    out = _callback(ring, LEAD + 5 * UP)
    tail = np.abs(out[LEAD + 4 * UP:])
    assert np.all(np.diff(tail) <= 0) and tail[0] < np.float32(0.13)
    assert ring.istate[MISSING] == 0
    out = _callback(ring, 2 * ring.fade)  # tick 5 never came: late
    assert not out[ring.fade:].any()  # zero once the fade is over (2 ms)
    assert ring.istate[MISSING] == 2 * ring.fade and ring.istate[UNDERRUNS] == 1


def test_resync_inserts_silence_and_stopping_fades_out():
    ring = _ring()
    _callback(ring, 200)  # the callback ran ahead of the tick loop (a stall before tick 0)
    assert ring.resync(0, 16) == 200 + 16 - LEAD and ring.position(0) == 216
    assert ring.resync(0, 16) == 0  # in time now
    ring.put(0, _block(0), 0, silent=False)
    out = _callback(ring, 64)
    np.testing.assert_array_equal(out[16:24], np.float32(0.1))
    ring.put(1, _block(1), 0, silent=False)
    ring.istate[STOPPING] = 1
    out = _callback(ring, 64)
    assert np.all(np.abs(out) < np.float32(0.1)) and not out[ring.fade:].any()  # stopping: fade, then zeros
    assert ring.istate[RECORDED] == 328


def test_compare_audio_accepts_silence_and_finds_a_real_difference():
    rng = np.random.default_rng(0)
    ticks = 50
    replay = np.concatenate([np.zeros(LEAD), rng.uniform(0.2, 0.8, ticks * UP)]).astype(np.float32)
    live = np.zeros(LEAD + ticks * UP + 40, dtype=np.float32)
    live[:replay.size] = replay
    # ticks 10-11 late: a fade over 16 frames then zeros; then a resync inserting 40 frames before tick 30
    p = LEAD + 10 * UP
    live[p:p + 16] = replay[p - 1] * (1 - np.arange(1, 17) / 16)
    q = LEAD + 30 * UP
    live[q:q + 40] = fade_from(live[q - 1:q], 40, 16)[:, 0]
    live[q + 40:] = replay[q:q + live.size - q - 40]
    cmp = compare_audio(live, replay, LEAD, UP, [[30, 40]], 16)
    assert cmp.ok and cmp.compared == ticks * UP and cmp.equal == ticks * UP - 16  # every tick frame but the fade
    assert cmp.silence == LEAD + 16 + 40  # the lead, the fade, the resync
    live[LEAD + 5 * UP] += np.float32(1e-6)  # one sample off by one part in a million
    cmp = compare_audio(live, replay, LEAD, UP, [[30, 40]], 16)
    assert not cmp.ok and cmp.first_unexplained == LEAD + 5 * UP


# The replay rebuilds the whole live stream from the ticks' samples and the logged timeline. Drive the ring as live
# does (ticks pushed, callbacks of any size in any interleaving, stalls, held ticks, a stop), log the timeline as live
# logs it, and rebuild: every frame handed to the "sound card" must come back bit for bit.


def test_resync_raises_the_margin_by_the_frames_late_up_to_the_most():
    ring = _ring()
    _callback(ring, LEAD + 30)  # tick 0 is 30 frames late
    assert ring.resync(0, 16, most=100) == 30 + 46 and ring.margin == 46  # 16 + 30 frames: this stall absorbed next time
    assert ring.position(0) == LEAD + 30 + 46
    _callback(ring, 46 + 200)  # 200 frames late now: the margin stops at the most
    assert ring.resync(0, 46, most=100) == 200 + 100 and ring.margin == 100
    _callback(ring, 100 + 5)
    assert ring.resync(0, 100, most=100) == 5 + 100 and ring.margin == 100  # at the most: fixed from now on
    ring2 = _ring()
    _callback(ring2, LEAD + 30)
    assert ring2.resync(0, 16) == 30 + 16 and ring2.margin == 16  # no most: the margin never grows


def _live_and_rebuilt(schedule, up, down, seed, most=0):
    from flowtex.dsp.audio_interp import frames_before
    from flowtex.runtime.audio_check import rebuild_live
    from flowtex.runtime.audio_timeline import AudioTimeline, SilenceRuns

    lead, ahead = 48, 24
    ring = AudioRing(up, 2, lead, RATE, record_s=1.0, down=down)
    n_ticks = sum(step[0] for step in schedule)
    rng = np.random.default_rng(seed)
    samples = rng.uniform(-0.9, 0.9, (frames_before(n_ticks, up, down), 2)).astype(np.float32)
    runs, silences, resyncs, handed = SilenceRuns(), [], [], []
    k = 0

    def drain():
        position, frames, classes = ring.drain()
        handed.append(frames)
        silences.extend(runs.feed(position, classes))

    for push, callback, held in schedule:
        for _ in range(push):
            gap = ring.resync(k, ahead, most)
            if gap:
                resyncs.append((k, gap))
                ahead = ring.margin
            a, b = frames_before(k, up, down), frames_before(k + 1, up, down)
            ring.put(k, samples[a:b], 0, silent=held)
            k += 1
        ring.fill(np.zeros((callback, 2), dtype=np.float32), 0)
        drain()
    ring.istate[STOPPING] = 1
    ring.fill(np.zeros((64, 2), dtype=np.float32), 0)
    drain()
    silences.extend(runs.close())
    live = np.concatenate(handed)
    timeline = AudioTimeline(lead=lead, fade=ring.fade, margin=24, resyncs=resyncs, silences=silences,
                             total=int(ring.istate[RECORDED]))
    rebuilt, klass = rebuild_live(samples, n_ticks, up, down, timeline)
    return live, rebuilt, klass, ring, timeline


def test_rebuilt_stream_equals_what_was_handed_over_through_stalls_holds_and_the_stop():
    # ticks in time, then a stall (the callback runs 300 frames with no tick: late, then a resync), held ticks, more
    schedule = [(10, 64, False), (8, 64, False), (0, 300, False), (5, 32, False), (4, 16, True), (12, 64, False),
                (0, 7, False), (6, 128, False)]
    live, rebuilt, klass, ring, _ = _live_and_rebuilt(schedule, UP, 1, 3)
    assert ring.istate[MISSING] > 0 and (klass == 2).any() and (klass == 3).any() and (klass == 4).any()
    np.testing.assert_array_equal(rebuilt, live)


def test_rebuilt_stream_at_441_over_10():
    schedule = [(3, 100, False), (0, 500, False), (4, 90, True), (6, 200, False)]
    live, rebuilt, _, _, _ = _live_and_rebuilt(schedule, 441, 10, 4)
    np.testing.assert_array_equal(rebuilt, live)


def test_rebuilt_stream_any_interleaving():
    from hypothesis import given, settings
    from hypothesis import strategies as st

    step = st.tuples(st.integers(0, 12), st.integers(1, 160), st.booleans())

    @settings(max_examples=60, deadline=None)
    @given(st.lists(step, min_size=1, max_size=12), st.integers(0, 2**31), st.sampled_from([0, 24, 40, 200]))
    def check(schedule, seed, most):  # most: the margin grows after each resync, up to it (0, 24: it never grows)
        live, rebuilt, _, _, _ = _live_and_rebuilt(schedule, UP, 1, seed, most)
        np.testing.assert_array_equal(rebuilt, live)

    check()


def test_check_audio_one_line_per_class_and_unexplained_differences():
    from dataclasses import replace

    from flowtex.runtime.audio_check import check_audio

    schedule = [(10, 64, False), (0, 300, False), (5, 32, False), (4, 16, True), (6, 128, False)]
    live, rebuilt, klass, _, timeline = _live_and_rebuilt(schedule, UP, 1, 5)
    ok = check_audio(live, rebuilt, klass, timeline, "live.wav", RATE)
    assert ok.unexplained == 0 and not any("DIFFER" in x for x in ok.lines)
    played = int((klass == 0).sum())
    assert f"{played} frames: the ticks' samples, equal to live.wav sample for sample" in ok.lines[1]
    assert any(x.endswith("the lead before tick 0") for x in ok.lines)
    assert any(x.endswith("ticks held by the input watchdog (a stale sensor)") for x in ok.lines)
    bad = live.copy()
    i = int(np.flatnonzero(klass == 0)[7])
    bad[i, 1] = np.nextafter(bad[i, 1], np.float32(2))  # one sample, one float32 step
    c = check_audio(bad, rebuilt, klass, timeline, "live.wav", RATE)
    assert c.unexplained == 1 and any(x.startswith(f"1 frames DIFFER (the ticks' samples), first at frame {i} ") for x in c.lines)
    longer = np.concatenate([live, np.zeros((5, 2), dtype=np.float32)])
    assert check_audio(longer, rebuilt, klass, timeline, "live.wav", RATE).unexplained == 5  # the log says how long
    cut = check_audio(longer, rebuilt, klass, replace(timeline, total=None), "live.wav", RATE)
    assert cut.unexplained == 0 and "the session log ends before them" in cut.lines[-1]  # a log without its END



def test_device_underflows_during_the_lead_are_not_underruns(tmp_path):
    # PortAudio's underflow flag while everything handed over was the lead's silence (a sound server's start) played
    # zeros for zeros: counted apart; after tick 0's first frame was due it is a click, an underrun
    from pathlib import Path
    from types import SimpleNamespace

    from flowtex.graph.compiled import load_graph
    from flowtex.io.audiomap import load_audio_section
    from flowtex.runtime.audio import AudioOutput

    repo = Path(__file__).resolve().parents[2]
    (tmp_path / "g.yaml").write_text("flowtex: 1\nname: vib\nrate: 1000\ninputs:\n  x: {}\nnodes:\n  v: {type: gain, params: {k: 0.5}}\n"
                                     "edges:\n  - x -> v.x\noutputs:\n  vibration: v.y\n")
    amap = load_audio_section(repo / "graphs" / "devices" / "example_audio_map.yaml", {"vibration": 1})
    out = AudioOutput(load_graph(tmp_path / "g.yaml").with_block_rows(1), amap)
    when = SimpleNamespace(outputBufferDacTime=0.0, currentTime=0.0)
    block = np.zeros((amap.block, 1), dtype=np.float32)
    out._callback(block, amap.block, when, SimpleNamespace(output_underflow=True))  # before tick 0 is placed
    out.place_tick0()
    assert out.lead == amap.block + 80  # one block handed over, then the 10 ms margin
    out._callback(block, amap.block, when, SimpleNamespace(output_underflow=True))  # still only lead silence handed over
    out._callback(block, amap.block, when, SimpleNamespace(output_underflow=False))
    out._callback(block, amap.block, when, SimpleNamespace(output_underflow=True))  # frames past the lead were due: a click
    summary = out.summary()
    assert (summary["lead_underflows"], summary["device_underflows"]) == (2, 1)
    assert summary["underruns"] == summary["late_callbacks"] + 1 and out.error is None
