"""Silently wrong or unclear (issue 27, section 6): ranges, conflicting options, replays of nothing, a self-fed delay,
plot suffixes, a render of nothing, merged grid cells, scheduler addresses, a NaN normal, a surface left with nothing.
Each case builds its input here; each refusal is one line naming the option or file, exit 1."""

from __future__ import annotations

import textwrap
import zipfile

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets import default_surface, friction_session, render_texture
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.canlog import SessionWriter
from flowtex.io.modelset import save_model_set
from flowtex.io.recordings import save_recording
from tests.cli.gain_graph import MAP_GRAPH
from tests.conftest import REPO
from tests.io.test_hostile_files import npy_header

DBC = REPO / "graphs" / "devices" / "example.dbc"
MAP = REPO / "graphs" / "devices" / "example_map.yaml"


def cli_one_line(capsys, argv: list[str], match: str) -> str:
    """Run ``flowtex ARGV``: exit 1 and one line containing ``match`` (a first run's compile notice aside)."""
    code = main(argv)
    err = [line for line in capsys.readouterr().err.splitlines() if line.strip() and not line.startswith("flowtex: compiling")]
    assert code == 1 and len(err) == 1 and len(err[0]) < 600, err
    assert match in err[0], err
    return err[0]


@pytest.fixture
def rec(tmp_path):
    """10 s at 1 kHz: accel, speed, force, position (3 axes), a 3-axis force."""
    rng = np.random.default_rng(1)
    n = 10000
    t = np.arange(n) / 1000.0
    pos = np.stack([100 * np.sin(t), 0 * t, 0 * t], axis=1)
    save_recording(tmp_path / "r.npz", {"accel": rng.normal(size=n), "speed": np.full(n, 100.0), "normal_force": np.full(n, 1.0),
                                        "position": pos, "force3": np.tile([0.3, 0.0, 1.0], (n, 1))}, rate=1000.0)
    return tmp_path / "r.npz"


RANGES = [
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--kg", "-1"], "--kg"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--kg", "0"], "--kg"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--kg", "nan"], "--kg"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--kg", "inf"], "--kg"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--r2-min", "-1"], "--r2-min"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--r2-min", "nan"], "--r2-min"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--r2-min", "2"], "--r2-min"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--force-range", "-1", "5"], "--force-range"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--force-range", "1", "inf"], "--force-range"),
    (["fit", "compliance", "R", "--force", "f", "--accel", "a", "-o", "o.json", "--force-range", "5", "1"], "--force-range"),
    (["fit", "taps", "R", "--accel", "a", "--force", "f", "--speed", "s", "-o", "t.json", "--length", "1e9"], "--length"),
    (["fit", "taps", "R", "--accel", "a", "--force", "f", "--speed", "s", "-o", "t.json", "--quiet", "1e9"], "--quiet"),
    (["run", "G", "--input", "R", "-o", "o.npz", "--seed", "-1"], "--seed"),
    (["simulate-device", "R", "--bus", "virtual", "--dbc", "D", "--map", "M", "--duration", "-1"], "--duration"),
    (["fit", "texture", "R", "--speed", "s", "-o", "s.json", "--scheduler", "not an address"], "--scheduler"),
    (["bench", "G", "-i", "R", "--knob", "k.k=1,2", "--scheduler", "not an address"], "--scheduler"),
]


@pytest.mark.parametrize("argv,option", RANGES, ids=[f"{a[0]}-{a[-2]}-{a[-1]}" for a, _ in RANGES])
def test_an_out_of_range_option_is_one_line_naming_it(capsys, argv, option):
    msg = cli_one_line(capsys, argv, option)
    assert "1e+12 ms" not in msg and "internal error" not in msg


def test_a_tap_length_below_one_sample_names_length(rec, capsys, tmp_path):
    cli_one_line(capsys, ["fit", "taps", str(rec), "--accel", "accel", "--force", "normal_force", "--speed", "speed",
                          "-o", str(tmp_path / "t.json"), "--length", "0.0001"], "--length 0.0001: less than one sample at 1000 Hz")


def test_holdout_leaving_nothing_to_fit(rec, capsys, tmp_path):
    cli_one_line(capsys, ["fit", "texture", str(rec), "--speed", "speed", "--force", "normal_force", "-o", str(tmp_path / "s.json"),
                          "--holdout", "0.999"], "--holdout 0.999 (--holdout-split tail) leaves 0.01 s to fit")


@pytest.mark.parametrize("verb", [["fit", "texture"], ["fit", "taps"]])
def test_speed_with_position_is_refused_naming_both(rec, capsys, tmp_path, verb):
    msg = cli_one_line(capsys, [*verb, str(rec), "--accel", "accel", "--force", "normal_force", "--speed", "speed",
                                "--position", "position", "-o", str(tmp_path / "o.json")], "--speed speed and --position position")
    assert not (tmp_path / "o.json").exists(), msg


def test_output_with_out_dir_is_refused_naming_both(rec, capsys, tmp_path):
    cli_one_line(capsys, ["fit", "texture", str(rec), "--speed", "speed", "-o", str(tmp_path / "S.json"), "--out-dir",
                          str(tmp_path / "D")], f"-o {tmp_path / 'S.json'} and --out-dir {tmp_path / 'D'}")
    assert not (tmp_path / "D").exists()


def test_a_negative_npy_dimension_is_refused(tmp_path, capsys):
    path = tmp_path / "neg.npz"
    with zipfile.ZipFile(path, "w") as zf:
        zf.writestr("x.npy", npy_header((-5,)) + b"\0" * 40)
    cli_one_line(capsys, ["plot", str(path), "-o", str(tmp_path / "p.png")], "claims shape (-5,)")


def test_a_delay_feeding_itself_is_refused_at_its_edge(tmp_path, capsys):
    g = tmp_path / "d.yaml"
    g.write_text(textwrap.dedent("""\
        flowtex: 1
        name: selfloop
        rate: 1000
        inputs: {x: {}}
        nodes:
          d: {type: delay}
          k: {type: gain, params: {k: 2}}
        edges:
          - d.y -> d.x
          - x -> k.x
        outputs: {y: k.y, z: d.y}
        """))
    msg = cli_one_line(capsys, ["validate", str(g), "--no-plugins"], "node 'd' feeds itself")
    assert msg.startswith(f"{g}:9:")


def test_plot_refuses_an_output_that_is_not_png(rec, capsys, tmp_path):
    cli_one_line(capsys, ["plot", str(rec), "-o", str(tmp_path / "p.npz")], "unknown output format '.npz'")
    assert not (tmp_path / "p.npz").exists()


def test_replays_of_nothing_are_refused(tmp_path, capsys):
    """An empty BLF, a BLF of unknown IDs, an empty and a garbage .log, a log whose one line is 5 MB: nothing to replay."""
    empty = tmp_path / "empty.blf"
    SessionWriter(empty).close()
    unknown = tmp_path / "unknown.blf"
    w = SessionWriter(unknown)
    import can

    for i in range(20):
        w.write(can.Message(arbitration_id=0x7AB, data=bytes(8), timestamp=1.0 + i * 1e-3), True)  # received, unknown
    w.close()
    (tmp_path / "empty.log").write_text("")
    (tmp_path / "garbage.log").write_bytes(b"\x00\xffnot a candump line\n" * 50)
    (tmp_path / "long.log").write_text("(1.0) vcan0 " + "A" * (5 << 20) + "\n")
    graph = tmp_path / "g.yaml"  # the inputs are the point, not the graph: the smallest one the map binds
    graph.write_text(MAP_GRAPH)
    says = {"empty.blf": ": nothing to replay", "unknown.blf": ": nothing to replay", "empty.log": ": nothing to replay",
            "garbage.log": ":1:2: byte 0xff is not text", "long.log": ":1: a line longer than 64 KiB"}  # text logs: the line
    for name, what in says.items():
        out = tmp_path / f"{name}.npz"
        cli_one_line(capsys, ["run", str(graph), "--input", str(tmp_path / name), "--dbc", str(DBC), "--map", str(MAP),
                              "-o", str(out), "--no-plugins"], f"{tmp_path / name}{what}")
        assert not out.exists()


def test_compare_on_a_recording_that_never_reaches_contact(tmp_path, capsys):
    ms = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2)
    save_model_set(ms, tmp_path / "s.json")
    n = 5000
    save_recording(tmp_path / "air.npz", {"accel": np.random.default_rng(0).normal(size=n), "speed": np.full(n, 100.0),
                                          "normal_force": np.zeros(n)}, rate=1000.0)
    msg = cli_one_line(capsys, ["compare", str(tmp_path / "s.json"), str(tmp_path / "air.npz"), "--speed", "speed"],
                       "nothing was rendered along this recording")
    assert "normal force reaches at most 0 N" in msg and "dB" not in msg


@pytest.mark.parametrize("argv, option, name", [
    (["compare", "s.json", "r.npz", "--speed", "speed"], "--json", "report.md"),
    (["compare", "s.json", "r.npz", "--speed", "speed"], "--json", "spectrum.png"),
    (["fit", "texture", "r.npz", "--speed", "speed", "-o", "out.json", "--folds", "2"], "--holdout-json", "report.md"),
    (["fit", "texture", "r.npz", "--speed", "speed", "-o", "out.json", "--folds", "2"], "--holdout-json", "plane.png"),
])
def test_an_output_that_is_a_file_of_the_report_is_refused(tmp_path, capsys, monkeypatch, argv, option, name):
    """compare --json rep/report.md --report rep wrote the JSON, then the report's markdown over it (and --holdout-json
    the same with fit texture's report): both were said written, one was lost. Refused before any work, naming both."""
    monkeypatch.chdir(tmp_path)
    for f in ("s.json", "r.npz"):
        (tmp_path / f).write_bytes(b"")
    cli_one_line(capsys, [*argv, option, f"rep/{name}", "--report", "rep"],
                 f"{option} rep/{name}: the report writes that file into rep")
    assert not (tmp_path / "rep" / name).exists()


def test_compare_on_a_recording_of_the_tool_at_rest_in_contact(tmp_path, capsys):
    """A HaTT-rule set (XML: silent corners at speed 0, HaTT's clamp to 0.0001 mm/s) leaves a faint render at rest, so a
    recording of the tool resting in contact was compared: figures of that residual against the sensor's noise, under
    a warning that the speed might be in other units. It is refused as at rest, naming the speed and the threshold."""
    from flowtex.io.hatt import write_hatt_xml

    ms = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2)
    write_hatt_xml(ms, tmp_path / "s.xml")
    n = 5000
    save_recording(tmp_path / "rest.npz", {"accel": 1e-4 * np.random.default_rng(0).normal(size=n), "speed": np.zeros(n),
                                           "normal_force": np.full(n, 1.0)}, rate=1000.0)
    msg = cli_one_line(capsys, ["compare", str(tmp_path / "s.xml"), str(tmp_path / "rest.npz"), "--speed", "speed"],
                       "the tool is at rest along this recording")
    assert "its speed reaches at most 0 mm/s, below the 0.05 mm/s" in msg and "dB" not in msg


@pytest.mark.parametrize("record, says", [
    ([1], "got [1]"), ("x", "got 'x'"), ({"from_hz": True}, "got True"), ({"from_hz": "500"}, "got '500'"),
    ({"from_hz": -5}, "got -5"), ({"from_hz": 0}, "got 0"),
    ({"from_hz": 1e-300}, "leaves the models a band up to 4e-301 Hz"), ({"from_hz": 20}, "leaves the models a band up to 8 Hz"),  # 0.8 x Nyquist
])
def test_compare_with_a_broken_resampling_record_is_one_line(tmp_path, capsys, record, says):
    """A JSON set's metadata is free-form; compare reads its 'resample' record for the band the models know. A list or
    text ended in an internal error, a from_hz of true or 1e-300 in a comparison over '12-0.4 Hz' of nan figures."""
    ms = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2)
    ms.metadata = {"resample": record}
    save_model_set(ms, tmp_path / "s.json")
    n = 5000
    save_recording(tmp_path / "r.npz", {"accel": np.random.default_rng(0).normal(size=n), "speed": np.full(n, 100.0),
                                        "normal_force": np.full(n, 1.0)}, rate=1000.0)
    msg = cli_one_line(capsys, ["compare", str(tmp_path / "s.json"), str(tmp_path / "r.npz"), "--speed", "speed"], says)
    assert msg.startswith(f"{tmp_path / 's.json'}: ") and "nan" not in msg


def test_grid_cells_at_one_point_say_what_was_dropped(tmp_path, capsys):
    truth = default_surface()
    cells = [(60.0, 0.8), (60.0, 2.4), (250.0, 0.8), (250.0, 0.8)]  # the last two at one (speed, force)
    lengths = [2000, 2000, 3000, 2000]
    acc = render_texture(truth, np.repeat([c[0] for c in cells], lengths), np.repeat([c[1] for c in cells], lengths), 1000.0)
    rows = ["file,speed,force"]
    start = 0
    for k, ((s, f), m) in enumerate(zip(cells, lengths, strict=True)):
        save_recording(tmp_path / f"cell{k}.npz", {"accel": acc[start:start + m]}, 1000.0)
        start += m
        rows.append(f"cell{k}.npz,{s},{f}")
    (tmp_path / "index.csv").write_text("\n".join(rows) + "\n")
    assert main(["fit", "texture", "--grid", str(tmp_path / "index.csv"), "--order", "6,4", "-o", str(tmp_path / "g.json")]) == 0
    out = capsys.readouterr().out
    assert "dropped: 1 cell(s) at (250 mm/s, 0.8 N), the point of a longer cell whose model was kept" in out, out


@pytest.mark.parametrize("index, match", [
    (b"file,speed,force\ncell.npz,nan,1\n", "index.csv:2: speed nan and force 1 must be finite and >= 0"),
    (b"file,speed,force\ncell.npz,60,1\ncell.npz,-60,1\n", "index.csv:3: speed -60 and force 1 must be finite and >= 0"),
    (b"file,speed,force\n,60,1\n", "index.csv:2: no file named in the 'file' column"),
    (bytes(range(200, 256)) * 20, "index.csv: not UTF-8 text at byte 0; a grid index is a CSV file"),
], ids=["nan", "negative", "no-file", "binary"])
def test_a_broken_grid_index_is_one_line_at_its_row(tmp_path, capsys, index, match):
    # a NaN or negative speed went on to "only one distinct (speed, force) point"; binary bytes were an internal error
    save_recording(tmp_path / "cell.npz", {"accel": np.random.default_rng(0).standard_normal(2000)}, 1000.0)
    (tmp_path / "index.csv").write_bytes(index)
    cli_one_line(capsys, ["fit", "texture", "--grid", str(tmp_path / "index.csv"), "-o", str(tmp_path / "g.json")], match)
    assert not (tmp_path / "g.json").exists()


def test_bench_on_a_dead_scheduler_is_one_line(tmp_path, capsys):
    save_recording(tmp_path / "in.npz", {"x": np.zeros(10)}, rate=1000.0)
    (tmp_path / "g.yaml").write_text("flowtex: 1\nname: g\nrate: 1000\ninputs: {x: {}}\nnodes: {k: {type: gain, params: {k: 1}}}\n"
                                     "edges: [x -> k.x]\noutputs: {y: k.y}\n")
    import dask.distributed  # its defaults loaded first, so leaving the context restores them, not nothing

    # a dead address (connection refused) fails at the connect timeout, however short: 0.5 s (30 s by default)
    with dask.config.set({"distributed.comm.timeouts.connect": "0.5s"}):
        cli_one_line(capsys, ["bench", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "in.npz"), "--knob", "k.k=1,2",
                              "--scheduler", "tcp://127.0.0.1:9"], "--scheduler tcp://127.0.0.1:9: cannot reach the Dask scheduler")


def test_fit_friction_nan_normal_names_normal(tmp_path, capsys):
    rec = friction_session(mu=0.4, duration_s=5.0, seed=3)
    n = rec.arrays["normal_force"].shape[0]
    save_recording(tmp_path / "f.npz", {"f3": np.tile([0.3, 0.0, 1.0], (n, 1))}, 1000.0)
    cli_one_line(capsys, ["fit", "friction", str(tmp_path / "f.npz"), "--force3", "f3", "--normal", "nan,0,1", "-o",
                          str(tmp_path / "mu.json")], "--normal nan,0,1: the normal vector must be three finite numbers")


def test_scene_plan_warns_when_a_surface_keeps_nothing(tmp_path, capsys):
    data = REPO / "graphs" / "data"
    (tmp_path / "scene.yaml").write_text(textwrap.dedent(f"""\
        flowtex: 1
        name: quiet
        rate: 1000
        trajectory: {{speed: [50, 250], force: [0.5, 2.5]}}
        thresholds: {{texture: 1000, friction: 5}}
        surfaces:
          glass:
            models: {data / 'synthetic_texture.json'}
            mu: 0.05
          rough:
            models: {data / 'rough_texture.json'}
            mu: 0.3
            keep: [texture]
        """))
    assert main(["scene", "plan", str(tmp_path / "scene.yaml"), "-o", str(tmp_path / "plan.yaml")]) == 0
    err = [line for line in capsys.readouterr().err.splitlines() if line.startswith("warning:")]
    assert len(err) == 1 and "surface 'glass' renders nothing" in err[0], err
    assert "threshold 1000" in err[0] and "threshold 5" in err[0], err


def test_simulating_a_recording_without_a_sensor_signal_names_the_file(tmp_path, capsys):
    # "recording has no signal 'position' ..." did not say which of the command's files it meant
    save_recording(tmp_path / "accel_only.npz", {"accel": np.zeros(100), "speed": np.zeros(100)}, rate=1000.0)
    msg = cli_one_line(capsys, ["live", str(REPO / "graphs" / "live_texture.yaml"), "--bus", "virtual", "--dbc", str(DBC),
                                "--map", str(MAP), "--simulate", str(tmp_path / "accel_only.npz"), "--duration", "0.2"],
                       "no signal 'position' for sensor input 'position' (it has: accel, speed)")
    assert msg.startswith(f"{tmp_path / 'accel_only.npz'}: ")


@pytest.mark.parametrize("group, word", [("fit", "KIND"), ("models", "ACTION"), ("plugin", "ACTION"), ("scene", "ACTION")])
def test_a_command_group_without_its_action_names_the_missing_word(capsys, group, word):
    # 'scene' and 'plugin' named their parser's internal field ('scene_command'), which the help shows nowhere
    line = cli_one_line(capsys, [group], f"the following arguments are required: {word} ")
    assert "_command" not in line and f"flowtex {group} --help" in line


@pytest.mark.parametrize("command", ["fit texture R --accel accel --force normal_force -o OUT",
                                     "fit taps R --accel accel --force normal_force -o OUT",
                                     "compare SURFACE R --accel accel --force normal_force"])
def test_motion_options_that_would_be_ignored_are_refused(rec, tmp_path, capsys, command):
    """--speed with --position: compare used --speed and dropped --position without a word (fit texture and fit taps
    refused it); --normal without --position (it is the surface normal the speed is computed from) was dropped by all
    three."""
    ms = synthetic_model_set(np.array([50.0, 150.0]), np.array([0.5, 1.5]), ar_order=2, ma_order=2)
    save_model_set(ms, tmp_path / "s0.json")
    names = {"R": str(rec), "OUT": str(tmp_path / "out.json"), "SURFACE": str(tmp_path / "s0.json")}
    argv = [names.get(a, a) for a in command.split()]
    cli_one_line(capsys, [*argv, "--speed", "speed", "--position", "position"], "give one")
    cli_one_line(capsys, [*argv, "--speed", "speed", "--normal", "position"],
                 "--normal position: the surface normal the speed is computed from with --position; give --position P")
    assert not (tmp_path / "out.json").exists()
