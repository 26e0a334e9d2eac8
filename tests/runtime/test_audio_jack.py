"""flowtex live's audio output against a real JACK server (dummy backend: paced in real time, no sound hardware).

Each test starts its own named jackd (JACK_DEFAULT_SERVER), a capture client
(tests/runtime/jack_capture.py, PortAudio's JACK host API) and ``flowtex live``
as a subprocess, connects flowtex's output port to the capture port with
``jack_connect`` as soon as it appears, and compares what JACK delivered with
``--record-audio``, JACK cycle by cycle: every cycle the capture got must be the
next block flowtex handed to PortAudio, except cycles jackd itself reports as an
XRun (a client not finished in time, on a loaded machine without real-time
scheduling). No timing asserts: latencies are checked for presence only.
Skipped only when jackd is not installed (.ci/run installs jackd2).
"""

from __future__ import annotations

import itertools
import json
import os
import re
import select
import shutil
import signal
import subprocess
import sys
import textwrap
import time
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.io import wavfile

from tests.cli.gain_graph import MAP_GRAPH as GRAPH  # two gains: what the audio path does is the point

REPO = Path(__file__).resolve().parents[2]
DBC = REPO / "graphs" / "devices" / "example.dbc"
CAPTURE = Path(__file__).with_name("jack_capture.py")
JACKD = shutil.which("jackd")
pytestmark = pytest.mark.skipif(JACKD is None, reason="jackd is not installed (Debian: apt-get install jackd2 libportaudio2)")
RATE = 8000
_names = itertools.count()

MAP = """
flowtex_map: 1
overrun_limit_ms: 100000    # a loaded test machine must not trip the overrun watchdog
inputs:
  position: {signals: [ToolPosition.PosX, ToolPosition.PosY, ToolPosition.PosZ], timeout_ms: 100000}
  normal_force: {signal: ToolForce.NormalForce, timeout_ms: 100000}
outputs:
  force: {signals: [ForceCmd.Fx, ForceCmd.Fy, ForceCmd.Fz], clamp: [-4, 4], safe: [0, 0, 0]}
audio:
  rate: 8000
  block: BLOCK
  margin_ms: MARGIN
  channels:
    - {output: vibration, scale: 1.5, clip: 1.0}
"""


@pytest.fixture
def setup(tmp_path):
    (tmp_path / "g.yaml").write_text(textwrap.dedent(GRAPH))
    rng = np.random.default_rng(7)
    n = 4000
    pos = np.zeros((n, 3))
    force = rng.uniform(0.5, 3.5, n)  # vibration 0.125..0.875 A: never zero, so the capture lines up unambiguously
    np.savez(tmp_path / "rec.npz", position=pos, normal_force=force, rate=np.float64(1000))
    return tmp_path


def _map(path: Path, block: int, margin_ms: float = 10.0) -> Path:
    m = path / f"m{block}.yaml"
    m.write_text(textwrap.dedent(MAP).replace("BLOCK", str(block)).replace("MARGIN", str(margin_ms)))
    return m


def _ports(env: dict) -> set[str]:
    out = subprocess.run(["jack_lsp"], capture_output=True, text=True, env=env, timeout=10)
    return set(out.stdout.split()) if out.returncode == 0 else set()


def _capture_port(env: dict, before: set[str]) -> str:
    """The capture client's input port, once jack_lsp lists it. Usually at once; on a loaded machine jack_lsp itself
    can fail or list the ports before the new one (a suite run saw no port there), so it is asked again, a few times a
    second, for up to 20 s."""
    end = time.monotonic() + 20
    while True:
        found = sorted(p for p in _ports(env) - before if ":in" in p)
        if found:
            return found[0]
        assert time.monotonic() < end, "the capture client's JACK port did not appear within 20 s"
        time.sleep(0.2)


class _PortEvents:
    """``jack_evmon``'s event lines: wakes the wait for a client's port at its registration, instead of polling
    ``jack_lsp`` (a JACK client of its own, and work for jackd: docs/testing.md) every few milliseconds while flowtex
    starts."""

    POLL_S = 0.5
    """Longest wait for an event (a port registered before the monitor saw it is found by the next poll)."""

    def __init__(self, proc: subprocess.Popen) -> None:
        self.fd = proc.stdout.fileno()

    def wait_port(self) -> None:
        """Return at the next port registration, or after :data:`POLL_S`."""
        end = time.monotonic() + self.POLL_S
        while (left := end - time.monotonic()) > 0 and select.select([self.fd], [], [], left)[0]:
            data = os.read(self.fd, 65536)
            if not data or re.search(rb"^Port \d+ registered$", data, re.MULTILINE):
                return


@contextmanager
def _port_events(env: dict):
    """A running ``jack_evmon`` (line-buffered through stdbuf), subscribed to the server's events when this yields."""
    proc = subprocess.Popen(["stdbuf", "-oL", "jack_evmon"], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, env=env)
    try:
        # its first line ("Graph reordered": its own activation) comes once it receives the server's events
        assert select.select([proc.stdout], [], [], 20)[0] and os.read(proc.stdout.fileno(), 65536), "jack_evmon did not start"
        yield _PortEvents(proc)
    finally:
        proc.terminate()  # it closes its JACK client and exits (SIGKILL would leave the server a dead client to drop)
        try:
            proc.wait(5)
        except subprocess.TimeoutExpired:  # its server is gone: closing the client hangs
            proc.kill()
            proc.wait()
        proc.stdout.close()


@contextmanager
def jack_server(period: int, log: Path):
    """A private jackd (dummy backend, RATE Hz, ``period`` frames) logging to ``log``; yields the environment that selects it."""
    name = f"flowtex-test-{os.getpid()}-{next(_names)}"
    env = {**os.environ, "JACK_DEFAULT_SERVER": name, "JACK_NO_START_SERVER": "1"}
    with open(log, "w") as out:
        proc = subprocess.Popen([JACKD, "--no-realtime", "-n", name, "-d", "dummy", "-r", str(RATE), "-p", str(period)],
                                stdout=out, stderr=subprocess.STDOUT, env=env, start_new_session=True)
    try:
        end = time.monotonic() + 20
        while "system:playback_1" not in _ports(env):
            assert proc.poll() is None and time.monotonic() < end, "jackd did not come up"
            time.sleep(0.05)
        yield env, proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(10)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        for left in Path("/dev/shm").glob(f"jack*{name}*"):  # what this server's clients left behind
            left.unlink(missing_ok=True)


STALL = """
import sys, time
from flowtex.runtime import simdevice
publish = simdevice.SimulatedDevice.publish
def stalled(self, k):  # the tick loop stops for 50 ms once, in its slack after tick 999 (a real stall of the loop)
    if k == 1000:
        time.sleep(0.05)
    return publish(self, k)
simdevice.SimulatedDevice.publish = stalled
from flowtex.cli import main
sys.exit(main())
"""


def _session(setup: Path, env: dict, block: int, duration: float, sigint_after: float | None = None,
             kill_server: Any = None, stall: bool = False, margin_ms: float = 10.0, busy: bool = False) -> dict:
    """Run flowtex live with its output connected to a capture client; returns what happened.

    ``stall``: run it through :data:`STALL` (the tick loop stops for 50 ms at tick 1000). ``busy``: one core kept busy
    by a process in this test's own process group from the moment flowtex's port appears (the session plays) to its end
    (not while flowtex starts: a busy core then only costs CPU)."""
    cap_path = setup / f"cap{block}.npy"
    before = _ports(env)
    hog = None
    cap = subprocess.Popen([sys.executable, str(CAPTURE), str(cap_path), str(RATE), str(block)], stdout=subprocess.PIPE,
                           text=True, env=env)
    try:
        assert cap.stdout.readline().strip() == "ready"
        cap_in = _capture_port(env, before)
        base = _ports(env)
        wav, blf, stats = setup / f"live{block}.wav", setup / f"s{block}.blf", setup / f"stats{block}.json"
        cmd = [sys.executable, *(("-c", STALL) if stall else ("-m", "flowtex")), "live", str(setup / "g.yaml"), "--bus", "virtual", "--dbc", str(DBC),
               "--map", str(_map(setup, block, margin_ms)), "--simulate", str(setup / "rec.npz"), "--duration", str(duration),
               "--record-audio", str(wav), "--record", str(blf), "--stats", str(stats), "--quiet"]
        with _port_events(env) as events:
            live = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, env=env)
            end = time.monotonic() + 180  # the first run compiles the graph: minutes on a cold cache and a loaded machine
            while True:
                outs = sorted(p for p in _ports(env) - base if ":out" in p)
                if outs:
                    subprocess.run(["jack_connect", outs[0], cap_in], check=True, env=env, timeout=10)
                    break
                assert live.poll() is None and time.monotonic() < end, f"flowtex never opened its JACK port: {live.stderr.read()}"
                events.wait_port()
        if busy:
            hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
        if sigint_after is not None:
            time.sleep(sigint_after)
            live.send_signal(signal.SIGINT)
        if kill_server is not None:
            time.sleep(1.0)
            kill_server()
        _, err = live.communicate(timeout=120)
        time.sleep(0.3)  # let the capture run past the end of flowtex's stream
    finally:
        if hog is not None:
            hog.kill()
            hog.wait(10)
        if kill_server is not None:  # no server left: the capture hangs in PortAudio and ignores SIGTERM (nothing to save)
            cap.kill()
        cap.terminate()
        try:
            cap.wait(20)
        except subprocess.TimeoutExpired:
            cap.kill()
            cap.wait()
    result = {"rc": live.returncode, "stderr": err, "wav": wav, "blf": blf}
    if cap_path.exists():
        result["captured"] = np.load(cap_path)
    if wav.exists():
        result["recorded"] = wavfile.read(wav)[1]
    if stats.exists():
        result["stats"] = json.loads(stats.read_text())
    return result


def _xruns(log: Path) -> int:
    """Cycles jackd reported as XRuns (its own timing, or a client not finished in time)."""
    return sum("XRun" in line for line in log.read_text(errors="replace").splitlines())


def _compare_cycles(captured: np.ndarray, recorded: np.ndarray, period: int) -> tuple[int, int]:
    """(cycles equal to the next recorded block, cycles that are not); after the recording ends the capture must be silent.

    An XRun costs one bad cycle, whichever way it went: jackd dropped blocks (the next captured cycle is a later
    recorded block), tore one (it matches nowhere, and the capture goes on at the next block), or played a cycle
    flowtex did not hand over (it matches nowhere, and the capture goes on at the same block: a stale or silent
    buffer). A cycle that matches nowhere therefore leaves the place in the recording where it is, and the next
    cycle decides between the last two."""
    c0, off, skipped = _line_up(captured, recorded, period)
    i = c0
    pos = i + off
    good, bad = 0, skipped
    unmatched = False  # the previous cycle matched nowhere (counted bad already)
    while i + period <= captured.size and pos + period <= recorded.size:
        block = captured[i:i + period]
        skip = next((j for j in range(0, 64) if np.array_equal(block, recorded[pos + j * period:pos + (j + 1) * period])), None)
        if skip is None:  # torn or inserted: counted once, the place in the recording kept
            bad += 1
            unmatched = True
        else:
            if skip == 0 or (unmatched and skip == 1):  # in step (after an inserted or a torn cycle, too)
                good += 1
            else:  # jackd dropped blocks
                bad += 1
            pos += (skip + 1) * period
            unmatched = False
        i += period
    assert not captured[i + period:].any(), "sound after flowtex's last recorded block"
    return good, bad


def test_compare_cycles_counts_each_xrun_once():
    # the comparison itself, on made-up captures: one XRun of each kind costs one bad cycle, not every later one
    period = 4
    rec = np.arange(1, 1 + 20 * period, dtype=np.float32)
    blocks = [rec[k * period:(k + 1) * period] for k in range(20)]
    silent = np.zeros(period, dtype=np.float32)
    torn = np.concatenate([blocks[5][:2], silent[:2]])
    cases = {
        "clean": (blocks, (20, 0)),
        "dropped two": (blocks[:5] + blocks[7:], (17, 1)),
        "torn": (blocks[:5] + [torn] + blocks[6:], (19, 1)),
        "silent cycle inserted": (blocks[:5] + [silent] + blocks[5:], (20, 1)),
        "stale cycle inserted": (blocks[:5] + [blocks[4]] + blocks[5:], (20, 1)),
        "torn then dropped": (blocks[:5] + [torn] + blocks[8:], (16, 2)),
    }
    for name, (captured, expected) in cases.items():
        cap = np.concatenate([silent, *captured, silent, silent])
        assert _compare_cycles(cap, rec, period) == expected, name


def _line_up(captured: np.ndarray, recorded: np.ndarray, period: int) -> tuple[int, int, int]:
    """(captured cycle start, its offset into the recording, sounding cycles before it that matched nowhere): the
    first captured cycle with sound that appears in the recording (an XRun may tear the first ones)."""
    first = int(np.flatnonzero(captured)[0])
    skipped = 0
    for c0 in range(first - first % period, captured.size - period, period):
        window = captured[c0:c0 + period]
        if not window.any():
            continue
        for r0 in np.flatnonzero(recorded == window[np.flatnonzero(window)[0]]):
            r0 -= int(np.flatnonzero(window)[0])
            if r0 >= 0 and np.array_equal(recorded[r0:r0 + period], window):
                return c0, int(r0) - c0, skipped
        skipped += 1
        assert skipped < 50, "the captured samples appear nowhere in --record-audio"
    raise AssertionError("the captured samples appear nowhere in --record-audio")


def test_captured_equals_record_audio_and_replay_at_period_64(setup, flowtex_cli):
    log = setup / "jackd.log"
    with jack_server(64, log) as (env, _):
        r = _session(setup, env, 64, duration=2.0)
    assert r["rc"] == 0, r["stderr"]
    good, bad = _compare_cycles(r["captured"], r["recorded"], 64)  # bit for bit: float32 through JACK
    assert bad <= _xruns(log), (good, bad)
    assert good * 64 > 0.5 * RATE * 2.0  # the capture saw most of the session
    rec = r["recorded"]

    audio = r["stats"]["audio"]
    assert set(audio) >= {"rate", "frames", "underruns", "latency_ms"}
    assert audio["rate"] == RATE and audio["frames"] == rec.size
    lat = audio["latency_ms"]
    assert 0 < lat["p50"] <= lat["p99"] <= lat["max"]

    done, replayed = _replay(flowtex_cli, setup, r, 64)
    assert done.returncode == 0, done.stdout + done.stderr
    np.testing.assert_array_equal(replayed, rec)  # the whole stream, silence included, sample for sample
    assert audio["played_frames"] > 0.5 * rec.size  # most of the session played the graph's samples, not safe silence
    assert "DIFFER" not in done.stdout and "the ticks' samples, equal to" in done.stdout

    tampered = setup / "tampered.wav"  # one sample off by one part in a million: --expect-audio finds it
    bad = rec.copy()
    i = audio["lead_frames"] + 8 * 500
    bad[i] = np.float32(bad[i] * (1 + 1e-6))
    wavfile.write(tampered, RATE, bad)
    done, _ = _replay(flowtex_cli, setup, r, 64, expect=tampered)
    assert done.returncode == 1 and f"1 frames DIFFER (the ticks' samples), first at frame {i} " in done.stdout, done.stdout


def _replay(cli, setup: Path, r: dict, block: int, expect: Path | None = None) -> tuple[subprocess.CompletedProcess, np.ndarray]:
    """``flowtex run`` on the session's log into a WAV, checked with --expect-audio (default: the live WAV); in this
    process (``cli``: the flowtex_cli fixture), since what is checked is the replay, not a process."""
    replay = setup / "replay.wav"
    done = cli("run", setup / "g.yaml", "--input", r["blf"], "--dbc", DBC, "--map", setup / f"m{block}.yaml", "--output", replay,
               "--expect-audio", expect or r["wav"])
    return done, (wavfile.read(replay)[1] if replay.exists() else np.zeros(0, dtype=np.float32))


def test_stall_longer_than_the_margin_resyncs_and_the_replay_still_equals_the_capture(setup, flowtex_cli):
    log = setup / "jackd.log"
    with jack_server(64, log) as (env, _):
        r = _session(setup, env, 64, duration=2.0, stall=True)
    assert r["rc"] == 0, r["stderr"]
    audio = r["stats"]["audio"]
    assert any(k >= 1000 for k, _ in audio["resyncs"]), audio["resyncs"]  # 50 ms > the 10 ms margin: silence inserted
    # the margin grew to absorb as long a stall next time, up to margin_max_ms (absent: 15 ms); 50 ms is beyond it
    assert (audio["margin_ms"], audio["margin_max_ms"], audio["margin_end_ms"]) == (10.0, 15.0, 15.0), audio
    good, bad = _compare_cycles(r["captured"], r["recorded"], 64)
    assert bad <= _xruns(log), (good, bad)
    done, replayed = _replay(flowtex_cli, setup, r, 64)
    assert done.returncode == 0, done.stdout + done.stderr
    np.testing.assert_array_equal(replayed, r["recorded"])  # over its whole length, the inserted silence included
    assert "resync(s) at tick(s)" in done.stdout and "ticks later than the margin (underruns)" in done.stdout


BUSY_MARGIN_MS = 40.0
"""The margin of the busy-core test (fixed: above the default maximum of 15 ms). The default (10 ms, growing to 15)
is measured with one core busy by benchmarks/bench_audio.py; this test runs on a shared machine whose other load it
does not control: there the loop thread wakes from its sleep up to 8-16 ms late whatever its priority (a plain
``time.sleep`` loop outside flowtex does the same; docs/live.md, "Where the stalls come from"), and this test with the
default margin had 37 and 49 late callbacks in 3 s at load 8-10. So it gives the loop more margin and checks the
mechanism: every stall shorter than the margin is caught up, and not one sample is lost."""


def test_cpu_bound_process_beside_the_session_costs_no_sample(setup):
    log = setup / "jackd.log"
    with jack_server(64, log) as (env, _):
        r = _session(setup, env, 64, duration=3.0, margin_ms=BUSY_MARGIN_MS, busy=True)  # one core busy while it plays
    assert r["rc"] == 0, r["stderr"]
    audio = r["stats"]["audio"]
    # no tick was late for the sound card: no late frame, no resync (the margin absorbed every stall of the loop);
    # the sound server's own xruns (jackd runs without real-time scheduling here) are counted apart and each one
    # is one jackd reports
    assert (audio["late_callbacks"], audio["late_frames"], audio["resyncs"]) == (0, 0, []), audio
    assert audio["device_underflows"] <= _xruns(log)
    assert audio["underruns"] == audio["device_underflows"]


def test_sigint_ends_in_silence_and_latency_at_period_256(setup):
    log = setup / "jackd.log"
    with jack_server(256, log) as (env, _):
        r = _session(setup, env, 256, duration=30.0, sigint_after=1.5)
    assert r["rc"] == 0, r["stderr"]  # SIGINT is a clean stop
    cap, rec = r["captured"], r["recorded"]
    good, bad = _compare_cycles(cap, rec, 256)
    assert good > 0 and bad <= _xruns(log), (good, bad)
    fade = r["stats"]["audio"]["fade_frames"]
    last = int(np.flatnonzero(cap)[-1])
    assert not cap[last + 1:].any() and cap.size - last > RATE // 10  # silence to the end of the capture
    tail = np.abs(cap[last - fade + 1:last + 1])
    assert np.all(np.diff(tail) < 0)  # the last sound is the fade, falling to zero within fade_frames (2 ms)
    assert tail[0] < np.abs(rec).max()
    lat = r["stats"]["audio"]["latency_ms"]
    assert 0 < lat["p50"] <= lat["p99"] <= lat["max"]


def test_vanished_device_ends_session_with_one_line(setup):
    with jack_server(64, setup / "jackd.log") as (env, server):
        r = _session(setup, env, 64, duration=30.0, kill_server=lambda: server.send_signal(signal.SIGTERM))
    assert r["rc"] == 1, r["stderr"]
    lines = [x for x in r["stderr"].strip().splitlines() if not x.startswith("flowtex: ")]  # notes: compiling, plugins
    assert len(lines) == 1 and "audio device" in lines[0] and "stopped" in lines[0], r["stderr"]


def _files_limited_to(size: int) -> None:
    """preexec_fn: every file the child writes is cut at ``size`` bytes (a write past it fails with EFBIG, as on a
    full disk; SIGXFSZ ignored so that the write fails instead of killing the child)."""
    import resource

    signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, resource.getrlimit(resource.RLIMIT_FSIZE)[1]))


def test_record_audio_the_disk_refuses_is_one_line_naming_it(setup):
    """--record-audio written at the end on a full disk: one line naming the option and the file, exit code 1, the older
    file left as it was (before: 'audio output: OSError: [Errno 27] File too large', naming neither)."""
    wav = setup / "live.wav"
    cmd = [sys.executable, "-m", "flowtex", "live", str(setup / "g.yaml"), "--bus", "virtual", "--dbc", str(DBC),
           "--map", str(_map(setup, 64)), "--simulate", str(setup / "rec.npz"), "--quiet", "--record-audio", str(wav)]
    with jack_server(64, setup / "jackd.log") as (env, _):
        warm = subprocess.run([*cmd, "--duration", "0.2"], capture_output=True, text=True, env=env, timeout=300)
        assert warm.returncode == 0, warm.stderr  # compiled and cached before any file is limited
        wav.write_bytes(b"an older recording")
        r = subprocess.run([*cmd, "--duration", "1"], capture_output=True, text=True, env=env, timeout=120,
                           preexec_fn=lambda: _files_limited_to(8000))  # 1 s at 8 kHz is 32 KB of float32
    lines = [x for x in r.stderr.strip().splitlines() if not x.startswith("flowtex: ")]
    assert r.returncode == 1 and len(lines) == 1, r.stderr
    assert lines[0].startswith(f"--record-audio {wav}: cannot write it (File too large)"), lines
    assert lines[0].endswith("(safe values sent)"), lines
    assert wav.read_bytes() == b"an older recording"
    assert sorted(p.name for p in setup.iterdir() if p.suffix == ".wav") == ["live.wav"]


NAN_AUDIO_GRAPH = GRAPH.replace("  v: {type: gain, params: {k: 0.25, unit: A}}",
                                "  big: {type: gain, params: {k: 1.0e308}}\n  neg: {type: gain, params: {k: -1.0e308}}\n"
                                "  v: {type: add}").replace(
    "  - normal_force -> v.x", "  - normal_force -> big.x\n  - normal_force -> neg.x\n  - big.y -> v.a\n  - neg.y -> v.b")
"""vibration = 1e308 f - 1e308 f: exactly 0 while 1e308 f is finite (f < 1.79), NaN (inf - inf) above."""


def test_nan_audio_is_counted_per_channel_in_stats_and_the_summary(setup):
    """Audio samples of a NaN graph output play as 0 and were counted nowhere: a session's stats said nothing about
    the graph's NaN audio. Now each audio channel's NaN/inf ticks are in the guard's ``nonfinite`` counts."""
    assert "big.y -> v.a" in NAN_AUDIO_GRAPH
    (setup / "g.yaml").write_text(textwrap.dedent(NAN_AUDIO_GRAPH))
    force = np.ones(4000)
    bad = np.r_[100:150, 300:310]
    force[bad] = 3.0  # 60 ticks of NaN vibration, well inside the 0.5 s session
    with np.errstate(over="ignore"):
        assert np.isfinite(1e308 * force).sum() == force.size - bad.size  # the overflow that makes them NaN
    np.savez(setup / "rec.npz", position=np.zeros((force.size, 3)), normal_force=force, rate=np.float64(1000))
    stats = setup / "stats.json"
    cmd = [sys.executable, "-m", "flowtex", "live", str(setup / "g.yaml"), "--bus", "virtual", "--dbc", str(DBC), "--map",
           str(_map(setup, 64)), "--simulate", str(setup / "rec.npz"), "--duration", "0.5", "--stats", str(stats)]
    with jack_server(64, setup / "jackd.log") as (env, _):
        r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads(stats.read_text())
    assert doc["ticks"] >= 400
    assert doc["nonfinite"] == {"force": 0, "audio channel 0 (vibration)": bad.size}
    assert f"guard     nonfinite force 0, audio channel 0 (vibration) {bad.size}" in r.stderr
    assert f"| nonfinite audio channel 0 (vibration) {bad.size}" in r.stderr  # the last status line
