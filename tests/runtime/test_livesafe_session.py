"""Live safety at start-up, session side: output paths and the simulated recording are checked before the first tick."""

from __future__ import annotations

import contextlib
import resource
import signal

import can
import cantools
import numpy as np
import pytest
from test_live import DBC, setup  # noqa: F401  (fixture; rootdir-relative import as pytest does)

from flowtex.cli import main as live_main
from flowtex.errors import DataError
from flowtex.graph.compiled import load_graph
from flowtex.io.atomic import OutputError
from flowtex.io.canlog import read_session
from flowtex.runtime.live import LiveConfig, run_live


def _live(setup, **kw):  # noqa: F811
    kw.setdefault("simulate", setup / "rec.npz")
    return run_live(load_graph(setup / "g.yaml"), LiveConfig(DBC, setup / "m.yaml", max_ticks=50, status=None, **kw))


@pytest.mark.parametrize("option,inp", [("--stats", "g.yaml"), ("--stats", "m.yaml"), ("--record", "rec.npz")])
def test_an_output_that_is_an_input_is_refused_before_the_session_and_left_intact(setup, option, inp, capsys):  # noqa: F811
    before = (setup / inp).read_bytes()
    args = ["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), "--simulate", str(setup / "rec.npz"),
            "--duration", "0.05", "--quiet", option, str(setup / inp)]
    if option == "--record":  # a .npz cannot be a CAN log: make the name a log that is the same file as the recording
        (setup / "rec.log").symlink_to(setup / inp)
        args[-1] = str(setup / "rec.log")
    assert live_main(args) == 1
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and "loaded plugin code" not in line]
    assert len(err) == 1 and err[0].startswith(f"{option} ") and "is an input of this command" in err[0], err
    assert (setup / inp).read_bytes() == before


def test_stats_and_record_into_missing_folders_are_created_before_the_session(setup):  # noqa: F811
    stats, rec = setup / "out" / "a" / "stats.json", setup / "logs" / "s.blf"
    r = _live(setup, stats_path=stats, record=rec)
    assert r.error is None and r.ticks == 50
    import json

    doc = json.loads(stats.read_text())
    assert doc["ticks"] == 50 and doc["frames_out"] == 100
    assert sum(not m.is_rx for m in read_session(rec)) == 2 * 51  # 50 ticks and the exit block
    assert sorted(p.name for p in rec.parent.iterdir()) == ["s.blf"]  # no temporary file left


def test_stats_and_record_on_one_file_and_a_folder_are_refused(setup):  # noqa: F811
    with pytest.raises(OutputError, match="--stats .*the same file as --record"):
        _live(setup, stats_path=setup / "s.log", record=setup / "s.log")
    (setup / "d.log").mkdir()
    with pytest.raises(OutputError, match=r"--record .*d\.log: is a folder"):
        _live(setup, record=setup / "d.log")
    (setup / "file").write_text("x")
    with pytest.raises(OutputError, match=r"--stats .*file is not a folder"):
        _live(setup, stats_path=setup / "file" / "stats.json")


def test_an_existing_record_is_replaced_only_by_a_complete_one(setup):  # noqa: F811
    rec = setup / "s.log"
    _live(setup, record=rec)
    first = rec.read_bytes()
    with pytest.raises(DataError):  # a session that cannot start (NaN below) leaves the old log as it was
        np.savez(setup / "nan.npz", position=np.zeros((10, 3)), normal_force=np.array([1.0] * 4 + [np.nan] * 6),
                 rate=np.float64(1000))
        _live(setup, record=rec, simulate=setup / "nan.npz")
    assert rec.read_bytes() == first


def test_nan_in_the_simulated_recording_is_refused_before_the_session(setup):  # noqa: F811
    """Not a ValueError from the encoder mid-session: one line naming the file, the signal and the first bad sample."""
    t = np.arange(400) / 1000.0
    force = 3 + np.sin(10 * np.pi * t)
    force[237] = np.nan
    force[300] = np.inf
    path = setup / "nan.npz"
    np.savez(path, position=np.zeros((400, 3)), normal_force=force, rate=np.float64(1000))
    with pytest.raises(DataError) as e:
        _live(setup, simulate=path, record=setup / "never.blf")
    msg = str(e.value)
    assert "\n" not in msg
    assert msg.startswith(f"{path}: signal 'normal_force' has 2 non-finite sample(s), the first (nan) at index 237")
    assert not (setup / "never.blf").exists()


def test_simulate_device_refuses_nan_before_opening_the_bus(setup, capsys):  # noqa: F811
    path = setup / "nan.npz"
    np.savez(path, position=np.full((20, 3), np.inf), normal_force=np.ones(20), rate=np.float64(1000))
    rc = live_main(["simulate-device", str(path), "--bus", "nosuchbus:0", "--dbc", str(DBC), "--map", str(setup / "m.yaml")])
    assert rc == 1
    err = capsys.readouterr().err
    assert "signal 'position' has 20 non-finite sample(s), the first (inf) at index 0" in err
    assert "nosuchbus" not in err  # refused before the (unknown) bus was tried


def test_files_the_session_was_built_from_are_inputs_too(setup):  # noqa: F811
    """``flowtex scene live SCENE --stats SCENE`` passes the scene file as one of the session's inputs."""
    scene = setup / "scene.yaml"
    scene.write_text("flowtex_scene: 1\n")
    with pytest.raises(OutputError, match=r"--stats .*scene\.yaml: that is an input of this command"):
        _live(setup, stats_path=scene, inputs=[scene])
    assert scene.read_text() == "flowtex_scene: 1\n"


@contextlib.contextmanager
def _files_limited_to(size: int):
    """Every file this process writes is cut at ``size`` bytes: a write past it fails with EFBIG, as on a full disk
    (RLIMIT_FSIZE; SIGXFSZ ignored so the write fails instead of killing the process)."""
    old_limit = resource.getrlimit(resource.RLIMIT_FSIZE)
    old_handler = signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    resource.setrlimit(resource.RLIMIT_FSIZE, (size, old_limit[1]))
    try:
        yield
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, old_limit)
        signal.signal(signal.SIGXFSZ, old_handler)


@pytest.mark.parametrize("suffix", [".log", ".blf"])
def test_a_record_the_disk_refuses_ends_the_session_in_one_line_with_safe_values_last(setup, suffix, capsys):  # noqa: F811
    """--record on a disk that fills mid-session: the session stops with the safe values as the last frames on the bus
    (read by a second python-can client, decoded with cantools), one line naming the log, exit code 1; the older log
    of that name is left as it was and no temporary file remains. Before: 'CAN bus error', then an internal error."""
    _live(setup)  # compiled (and cached) before any file is limited
    rec = setup / f"s{suffix}"
    rec.write_bytes(b"an older log")
    channel = f"livesafe-disk-{suffix[1:]}"
    db = cantools.database.load_file(DBC)
    listener = can.Bus(interface="virtual", channel=channel, receive_own_messages=False)
    try:
        with _files_limited_to(16_000):
            rc = live_main(["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), "--simulate",
                            str(setup / "rec.npz"), "--bus", f"virtual:{channel}", "--duration", "3", "--quiet",
                            "--record", str(rec)])
        frames = []
        msg = listener.recv(0)
        while msg is not None:
            frames.append(msg)
            msg = listener.recv(0)
    finally:
        listener.shutdown()
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and not line.startswith("flowtex: compiling")]
    assert rc == 1 and len(err) == 1, err
    assert f"--record {rec}: cannot write the CAN log: File too large" in err[0] and err[0].endswith("(safe values sent)"), err
    assert "CAN bus error" not in err[0]
    current = [db.decode_message(0x200, m.data)["Current"] for m in frames if m.arbitration_id == 0x200]
    force = [[db.decode_message(0x201, m.data)[k] for k in ("Fx", "Fy", "Fz")] for m in frames if m.arbitration_id == 0x201]
    assert 100 < len(current) < 3000, len(current)  # the session ran, and stopped before its 3 s
    assert current[-1] == 0.0 and force[-1] == [0, 0, 0]
    assert current[-2] > 0.4  # the tick before was a live one
    assert rec.read_bytes() == b"an older log"
    assert sorted(p.name for p in setup.iterdir() if p.name.startswith((".s", "s."))) == [rec.name]


def test_stats_the_disk_refuses_are_one_line_after_the_session(setup, capsys):  # noqa: F811
    """--stats written at the end on a full disk: one line naming it, exit code 1, the older file left as it was
    (before: an internal error, and the session's summary and warnings lost)."""
    _live(setup)  # compiled (and cached) before any file is limited
    stats = setup / "stats.json"
    stats.write_text("{}")
    with _files_limited_to(300):  # the statistics are a few KB
        rc = live_main(["live", str(setup / "g.yaml"), "--dbc", str(DBC), "--map", str(setup / "m.yaml"), "--simulate",
                        str(setup / "rec.npz"), "--duration", "0.2", "--quiet", "--stats", str(stats)])
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and not line.startswith("flowtex: compiling")]
    assert rc == 1 and len(err) == 1, err
    assert err[0].startswith(f"--stats {stats}: cannot write it (File too large)") and err[0].endswith("(safe values sent)"), err
    assert stats.read_text() == "{}"
    assert sorted(p.name for p in setup.iterdir() if "stats" in p.name) == ["stats.json"]
