"""`flowtex run`, `graph`, `nodes` from the command line, and recording formats."""

from __future__ import annotations

import shlex
import shutil
import subprocess
import sys

import numpy as np
import pytest

import flowtex
from flowtex.cli import main
from flowtex.errors import DataError
from flowtex.io.recordings import load_recording, save_recording
from tests.conftest import REPO

GRAPH = """
flowtex: 1
name: t
rate: 1000
inputs:
  p: {shape: [3], unit: mm}
  f: {unit: N}
nodes:
  lp: {type: first_order_lowpass, params: {cutoff_hz: 30}}
  mag: {type: norm}
  g: {type: gain, params: {k: 2}}
edges:
  - p -> lp.x
  - lp.y -> mag.x
  - f -> g.x
outputs:
  smooth: lp.y
  speed: mag.y
  force: g.y
"""


@pytest.fixture
def rec():
    rng = np.random.default_rng(3)
    return {"p": rng.standard_normal((1500, 3)), "f": rng.standard_normal(1500)}


@pytest.mark.parametrize("suffix", [".npz", ".csv", ".h5"])
def test_run_reads_and_writes_every_format(write_graph, tmp_path, rec, suffix, capsys):
    graph = write_graph(GRAPH)
    src = tmp_path / f"in{suffix}"
    dst = tmp_path / f"out{suffix}"
    save_recording(src, rec, rate=1000)
    assert main(["run", str(graph), "--input", str(src), "--output", str(dst)]) == 0
    assert "1500 ticks" in capsys.readouterr().out
    out = load_recording(dst)
    assert out.rate == 1000
    expected = flowtex.load_graph(graph).run(rec)
    for name, value in expected.items():
        np.testing.assert_array_equal(out.arrays[name], value)  # CSV uses repr: exact round trip


def test_csv_vector_columns(tmp_path):
    path = tmp_path / "r.csv"
    path.write_text("# rate: 500\np[0],p[1],f\n1,2,3\n4,5,6\n")
    rec = load_recording(path)
    assert rec.rate == 500
    np.testing.assert_array_equal(rec.arrays["p"], [[1, 2], [4, 5]])
    np.testing.assert_array_equal(rec.arrays["f"], [3, 6])


@pytest.mark.parametrize("content, message", [
    ("p[0],p[2]\n1,2\n", "lacks column(s) p[1]"),
    ("a,b\n1,2,3\n", ":2: 3 values but 2 columns"),
    ("a\nx\n", ":2: non-numeric value"),
])
def test_bad_csv_errors_name_file_and_line(tmp_path, content, message):
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(DataError) as info:
        load_recording(path)
    assert str(info.value).startswith(str(path)) and message in str(info.value)


def test_recording_rate_must_match_graph(write_graph, tmp_path, rec, capsys):
    graph = write_graph(GRAPH)
    src = tmp_path / "in.npz"
    save_recording(src, rec, rate=800)
    assert main(["run", str(graph), "--input", str(src)]) == 1
    err = capsys.readouterr().err
    assert "recorded at 800 Hz but graph 't' runs at 1000 Hz" in err and "Traceback" not in err
    # the command it suggests runs as given (OUT.npz filled in), and its output then runs through the graph
    command = err[err.index("'flowtex ") + len("'flowtex "):err.index("' and use OUT.npz")]
    assert "--set rate=800" in err
    out = tmp_path / "resampled.npz"
    assert main(shlex.split(command.replace("OUT.npz", str(out)))) == 0
    assert load_recording(out).rate == 1000
    assert main(["run", str(graph), "--input", str(out), "-o", str(tmp_path / "y.npz")]) == 0


def test_a_set_path_is_read_from_the_current_folder(tmp_path, monkeypatch, capsys):
    """Every path given on the command line is read from where the command runs (--input, -o); a --set path too. Before,
    it was read from the graph file's folder: `--set lookup.models=surface.json` beside the user's recording was "no such
    model file graphs/surface.json", the command the bundled graph's comment suggests for a user's own rig."""
    shutil.copy(REPO / "graphs" / "data" / "synthetic_texture.json", tmp_path / "surface.json")
    monkeypatch.chdir(tmp_path)
    argv = ["run", str(REPO / "graphs" / "speed_force_texture.yaml"), "--input", str(REPO / "graphs" / "data" / "speed_force.npz"),
            "--set", "lookup.models=surface.json", "--set", "friction.models=null", "--set", "friction.mu=0.3", "-o", "out.npz"]
    assert main(argv) == 0, capsys.readouterr().err
    assert (tmp_path / "out.npz").exists()
    (tmp_path / "surface.json").unlink()  # and a missing one is named where it was looked for
    assert main(argv) == 1
    assert f"{tmp_path / 'surface.json'}: " in capsys.readouterr().err


def test_missing_input_signal_is_named(write_graph, tmp_path, rec, capsys):
    src = tmp_path / "in.npz"
    save_recording(src, {"p": rec["p"]})
    assert main(["run", str(write_graph(GRAPH)), "--input", str(src)]) == 1
    assert "lacks graph input(s) f (the file has: p)" in capsys.readouterr().err


def test_seed_and_set_options(write_graph, tmp_path, rec):
    graph = write_graph(GRAPH)
    src = tmp_path / "in.npz"
    save_recording(src, rec)
    assert main(["run", str(graph), "-i", str(src), "-o", str(tmp_path / "a.npz"), "--set", "g.k=5", "--seed", "3"]) == 0
    np.testing.assert_array_equal(np.load(tmp_path / "a.npz")["force"], 5 * rec["f"])


def test_graph_command_shows_order_dropped_dot_and_code(write_graph, capsys):
    graph = write_graph(GRAPH.replace("  force: g.y\n", ""))
    assert main(["graph", str(graph)]) == 0
    text = capsys.readouterr().out
    assert "execution order:" in text and "1. lp (first_order_lowpass)" in text
    assert "dropped (no output depends on them): g" in text
    assert main(["graph", str(graph), "--dot"]) == 0
    assert capsys.readouterr().out.startswith('digraph "t"')
    assert main(["graph", str(graph), "--show-code"]) == 0
    code = capsys.readouterr().out
    assert "def block(f, i, n):" in code and "# lp: first_order_lowpass" in code


def test_nodes_command_lists_ports_and_params(capsys):
    assert main(["nodes"]) == 0
    text = capsys.readouterr().out
    for name in ("butterworth", "white_noise", "delay", "gain", "biquad", "differentiator"):
        assert f"\n{name} — " in "\n" + text
    assert main(["nodes", "butterworth"]) == 0
    text = capsys.readouterr().out
    assert "cutoff_hz" in text and "lowpass|highpass|bandpass|bandstop" in text and "required" in text
    assert main(["nodes", "buterworth"]) == 1
    assert "did you mean 'butterworth'" in capsys.readouterr().err


def test_plugins_option_and_environment(tmp_path, write_graph, monkeypatch, capsys):
    plugdir = tmp_path / "myplugins"
    plugdir.mkdir()
    (plugdir / "twice.py").write_text(
        "import numpy as np\nfrom numba import njit\nfrom flowtex.node_api import Node, Port\n\n"
        "@njit(cache=True)\ndef k(p, s, si, x, y):\n    for t in range(x.shape[0]):\n        y[t, 0] = 2 * x[t, 0]\n\n"
        "class Twice(Node):\n    '''Double it.'''\n    type_name = 'twice_test'\n"
        "    inputs = {'x': Port((), '*')}\n    outputs = {'y': Port((), '=x')}\n    kernel = k\n")
    graph = write_graph("flowtex: 1\nname: p\nrate: 100\ninputs: {x: {}}\nnodes: {t: {type: twice_test}}\n"
                        "edges: [x -> t.x]\noutputs: {y: t.y}\n")
    monkeypatch.chdir(tmp_path)
    assert main(["validate", str(graph)]) == 1
    assert "unknown node type 'twice_test'" in capsys.readouterr().err
    assert main(["validate", str(graph), "--plugins", str(plugdir)]) == 0
    monkeypatch.setenv("FLOWTEX_PLUGINS", str(plugdir))
    assert main(["validate", str(graph)]) == 0
    g = flowtex.load_graph(graph)
    np.testing.assert_array_equal(g.run({"x": np.arange(4.0)})["y"], [0, 2, 4, 6])


def test_broken_plugin_is_reported_with_its_file_and_line(tmp_path, write_graph, capsys):
    plugdir = tmp_path / "bad"
    plugdir.mkdir()
    (plugdir / "oops.py").write_text("x = 1\nraise RuntimeError('boom')\n")
    assert main(["nodes", "--plugins", str(plugdir)]) == 1
    err = capsys.readouterr().err
    assert f"{plugdir / 'oops.py'}:2: plugin failed to load: RuntimeError: boom" in err


def test_console_script_is_installed():
    out = subprocess.run([sys.executable, "-m", "flowtex", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.startswith("flowtex ")


def test_set_null_swaps_a_model_sets_friction_for_a_coefficient(tmp_path, capsys):
    """graphs/speed_force_texture.yaml's header: a fitted surface (no mu) for the lookup and a number for the friction.

    The graph file names ``friction.models``; ``mu`` and ``models`` exclude each other, so a user who renders a surface
    without mu needs ``--set friction.models=null`` to give ``--set friction.mu``: the rendered friction is then
    HaTT's Coulomb rule with that mu (0.3 x the normal force above mu/0.004 mm/s).
    """
    from flowtex.datasets.model_sets import synthetic_model_set
    from flowtex.io.modelset import save_model_set

    surface = tmp_path / "surface.json"
    save_model_set(synthetic_model_set([60.0, 120.0], [0.5, 1.5], ar_order=4, ma_order=2, mu=None), surface)
    n = 600
    src = tmp_path / "rig.npz"
    save_recording(src, {"speed": np.full(n, 150.0), "normal_force": np.full(n, 2.0)}, rate=1000.0)
    base = ["run", str(REPO / "graphs" / "speed_force_texture.yaml"), "-i", str(src), "-o", str(tmp_path / "out.npz"),
            "--set", f"lookup.models={surface}", "--compile", "dispatch"]
    assert main([*base, "--set", f"friction.models={surface}"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--set friction.models=null --set friction.mu=0.3" in err[0], err
    assert main([*base, "--set", "friction.models=null", "--set", "friction.mu=0.3"]) == 0, capsys.readouterr().err
    friction = load_recording(tmp_path / "out.npz").arrays["friction_force"]
    assert np.allclose(friction, 0.3 * 2.0)  # 150 mm/s > 0.3/0.004 = 75 mm/s: Coulomb, mu F_n


def test_a_replay_of_a_missing_log_or_without_its_device_files_is_said_before_the_compile(tmp_path, monkeypatch, capsys):
    """Replaying a CAN session: a missing log, DBC or map cost a compile (25 s with an empty cache) before one line."""
    from flowtex.graph import compiled

    def no_compile(*args, **kwargs):
        raise AssertionError("the graph was compiled before the session's files were read")

    monkeypatch.setattr(compiled.Graph, "__init__", no_compile)
    devices = REPO / "graphs" / "devices"
    argv = ["run", str(REPO / "graphs" / "live_texture.yaml"), "-o", str(tmp_path / "out.npz")]
    (tmp_path / "cut.blf").write_bytes(b"LOGG" + bytes(60))
    for extra, message in (
            (["--input", str(tmp_path / "missing.blf"), "--dbc", str(devices / "example.dbc"), "--map",
              str(devices / "example_map.yaml")], f"{tmp_path / 'missing.blf'}: CAN log not found"),
            (["--input", str(tmp_path / "cut.blf")], f"{tmp_path / 'cut.blf'}: replaying a CAN session needs --dbc"),
            (["--input", str(tmp_path / "cut.blf"), "--dbc", str(devices / "example.dbc"), "--map",
              str(devices / "example_map.yaml")], f"{tmp_path / 'cut.blf'}: ")):
        assert main([*argv, *extra]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(message), err


@pytest.mark.parametrize("verb", ["run", "scene"])
def test_a_missing_or_broken_recording_is_said_before_the_graph_is_compiled(tmp_path, monkeypatch, capsys, verb):
    """A typo in --input, or a recording of other signals or at another rate, used to cost a whole numba compile
    (seconds idle, a minute under load) before one line said so."""
    from flowtex.graph import compiled

    def no_compile(*args, **kwargs):
        raise AssertionError("the graph was compiled before the recording was read")

    monkeypatch.setattr(compiled.Graph, "__init__", no_compile)
    (tmp_path / "cut.npz").write_bytes(b"PK\x03\x04" + bytes(40))
    graphs = REPO / "graphs"
    argv = (["run", str(graphs / "hatt_texture.yaml")] if verb == "run"
            else ["scene", "run", str(graphs / "scene_two_surfaces.yaml")])
    save_recording(tmp_path / "other.npz", {"accel": np.zeros(100)}, rate=1000.0)       # lacks the graph's inputs
    save_recording(tmp_path / "fast.npz", {"position": np.zeros((100, 3)), "normal_force": np.zeros(100),
                                           "normal": np.zeros((100, 3)), "surface": np.zeros(100)}, rate=2000.0)
    for name, message in (("missing.npz", "recording not found"), ("cut.npz", "not a readable .npz recording"),
                          ("other.npz", "lacks graph input(s) "), ("fast.npz", "recorded at 2000 Hz but graph ")):
        assert main([*argv, "--input", str(tmp_path / name), "-o", str(tmp_path / "out.npz")]) == 1
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and err[0].startswith(f"{tmp_path / name}: {message}"), err
    assert not (tmp_path / "out.npz").exists()


def test_set_node_every_applies_what_a_bench_knob_found(write_graph, tmp_path, rec, capsys):
    """`bench --knob lookup.every=1,4` sweeps the node key `every`; `run --set NODE.every=K` used to refuse it as an unknown
    parameter, so a sweep's result could not be used without editing the file. It equals `every: K` written in the file."""
    from flowtex.graph.spec import load_spec

    graph = write_graph(GRAPH)
    src = tmp_path / "in.npz"
    save_recording(src, rec, rate=1000.0)
    assert main(["run", str(graph), "-i", str(src), "-o", str(tmp_path / "set.npz"), "--set", "lp.every=4"]) == 0
    every4 = write_graph(GRAPH.replace("{type: first_order_lowpass, params: {cutoff_hz: 30}}",
                                       "{type: first_order_lowpass, params: {cutoff_hz: 30}, every: 4}"), "every4.yaml")
    assert load_spec(every4).nodes["lp"].every == 4 == load_spec(graph, {"lp.every": 4}).nodes["lp"].every
    assert main(["run", str(every4), "-i", str(src), "-o", str(tmp_path / "file.npz")]) == 0
    a, b = load_recording(tmp_path / "set.npz").arrays, load_recording(tmp_path / "file.npz").arrays
    assert np.array_equal(a["smooth"], b["smooth"])
    assert np.array_equal(a["smooth"][1:4], np.repeat(a["smooth"][:1], 3, axis=0))  # held for 3 ticks after tick 0
    assert not np.array_equal(a["smooth"][4], a["smooth"][0])                          # and run again at tick 4
    capsys.readouterr()
    assert main(["run", str(graph), "-i", str(src), "-o", str(tmp_path / "bad.npz"), "--set", "lp.every=0"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("--set lp.every: ") and "every must be a positive integer" in err[0], err


def test_a_recording_stating_another_unit_than_an_input_is_refused(write_graph, tmp_path, rec, capsys):
    """A recording that states its units (docs/recordings.md) is refused where one differs from the graph input's:
    flowtex converts no unit, and before a position in m ran through an input in mm as if it were mm (1000x too
    small), silently. The same unit written another way, or a unit the file leaves unstated, runs."""
    graph = write_graph(GRAPH)
    src = tmp_path / "in.npz"
    out = tmp_path / "out.npz"
    save_recording(src, rec, rate=1000, units={"p": "m", "f": "N"})
    assert main(["run", str(graph), "--input", str(src), "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert (f"{src}: signal 'p' is in 'm' (the file's units) but graph 't' input 'p' takes mm; flowtex converts no unit: "
            "multiply it by 1000 and state its unit as mm") in err
    assert not out.exists()
    save_recording(src, rec, rate=1000, units={"f": "kg*m/s^2/kg*kg"})  # no rule converts kg m/s^2 to N: no factor named
    assert main(["run", str(graph), "--input", str(src), "-o", str(out)]) == 1
    assert "graph 't' input 'f' takes N; flowtex converts no unit: convert it to N and state that unit" in capsys.readouterr().err
    for units in ({"p": "mm", "f": "N"}, {"p": "mm*s/s"}, {"p": "mm*mm²/mm^2"}, {"p": "mm s / s", "f": " N "}, {"f": "-"}, {}):
        save_recording(src, rec, rate=1000, units=units)
        assert main(["run", str(graph), "--input", str(src), "-o", str(out)]) == 0, (units, capsys.readouterr().err)
