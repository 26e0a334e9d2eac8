"""The one writer wired into every verb (issue 17): no verb overwrites an input, writes into a read-only folder after its
work, or leaves a folder rule of its own. Every case here fails before any work, so none compiles a graph."""

from __future__ import annotations

import os
import stat

import numpy as np
import pytest

from flowtex.cli import main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.modelset import save_model_set
from flowtex.io.recordings import save_recording
from tests.cli.gain_graph import GAIN_GRAPH as GRAPH
from tests.conftest import REPO

SCENE = REPO / "graphs" / "scene_two_surfaces.yaml"
DBC = REPO / "graphs" / "devices" / "example.dbc"
MAP = REPO / "graphs" / "devices" / "example_map.yaml"


@pytest.fixture
def files(tmp_path):
    """A graph, a recording (x, accel, speed, normal_force; 1 kHz), a model set, a scene copy: name -> path."""
    (tmp_path / "g.yaml").write_text(GRAPH)
    rng = np.random.default_rng(0)
    n = 2000
    save_recording(tmp_path / "in.npz", {"x": rng.normal(size=n), "accel": rng.normal(size=n), "speed": np.full(n, 100.0),
                                         "normal_force": np.full(n, 1.0)}, rate=1000.0)
    save_model_set(synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2), tmp_path / "m.json")
    return {"graph": tmp_path / "g.yaml", "rec": tmp_path / "in.npz", "models": tmp_path / "m.json"}


def _run(capsys, argv):
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    return code, err


INPUT_CASES = {
    "run": lambda f: (["run", f["graph"], "--input", f["rec"], "-o", f["rec"]], f["rec"], "-o"),
    "fit texture": lambda f: (["fit", "texture", f["rec"], "--speed", "speed", "-o", f["rec"]], f["rec"], "-o"),
    "bench": lambda f: (["bench", f["graph"], "-i", f["rec"], "--knob", "k.k=1,2", "-o", f["rec"]], f["rec"], "-o"),
    "scene plan": lambda f: (["scene", "plan", f["graph"], "-o", f["graph"]], f["graph"], "-o"),
    "live --stats": lambda f: (["live", f["graph"], "--dbc", DBC, "--map", MAP, "--stats", f["graph"]], f["graph"], "--stats"),
    "resample": lambda f: (["resample", f["rec"], "--rate", "500", "-o", f["rec"]], f["rec"], "-o"),
    "models resample": lambda f: (["models", "resample", f["models"], "--rate", "500", "-o", f["models"]], f["models"], "-o"),
    "plot": lambda f: (["plot", f["rec"], "-o", f["rec"]], f["rec"], "-o"),
    "compare --json": lambda f: (["compare", f["models"], f["rec"], "--speed", "speed", "--json", f["models"]], f["models"], "--json"),
}


@pytest.mark.parametrize("verb", list(INPUT_CASES))
def test_an_output_that_is_an_input_is_refused_and_the_input_kept(files, capsys, verb):
    argv, victim, option = INPUT_CASES[verb](files)
    before = victim.read_bytes()
    code, err = _run(capsys, argv)
    assert code == 1 and len(err) == 1, err
    assert err[0].startswith(f"{option} {victim}: that is an input of this command") and "never overwrites an input" in err[0]
    assert victim.read_bytes() == before


def test_the_same_file_spelled_another_way_is_still_an_input(files, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    os.symlink("in.npz", tmp_path / "alias.npz")
    before = files["rec"].read_bytes()
    for out in ("./in.npz", "alias.npz", f"{tmp_path}/sub/../in.npz"):
        (tmp_path / "sub").mkdir(exist_ok=True)
        code, err = _run(capsys, ["resample", "in.npz", "--rate", "500", "-o", out])
        assert code == 1 and "that is an input" in err[0], (out, err)
    assert files["rec"].read_bytes() == before


def test_every_writer_refuses_a_read_only_folder_before_its_work(files, capsys, tmp_path, monkeypatch):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    if os.geteuid() == 0:  # root may write anywhere: make check_output's os.access see the folder as read-only
        real = os.access
        monkeypatch.setattr(os, "access", lambda p, mode, **kw: False if os.fspath(p) == os.fspath(ro) else real(p, mode, **kw))
    _read_only_cases(files, capsys, tmp_path)


def _read_only_cases(files, capsys, tmp_path):
    ro = tmp_path / "ro"
    f = files
    cases = [
        ["run", f["graph"], "--input", f["rec"], "-o", ro / "o.npz"],
        ["fit", "texture", f["rec"], "--speed", "speed", "-o", ro / "s.json"],
        ["fit", "texture", f["rec"], "--speed", "speed", "-o", tmp_path / "s.json", "--xml", ro / "s.xml"],
        ["fit", "friction", f["rec"], "--force", "normal_force", "--friction-force", "x", "-o", ro / "mu.json"],
        ["fit", "taps", f["rec"], "--accel", "accel", "--force", "normal_force", "--speed", "speed", "-o", ro / "t.json"],
        ["fit", "pattern", f["rec"], "--accel", "accel", "--position", "x", "-o", ro / "p.json"],
        ["fit", "compliance", f["rec"], "--force", "normal_force", "--accel", "accel", "-o", ro / "c.json"],
        ["bench", f["graph"], "-i", f["rec"], "--knob", "k.k=1,2", "-o", ro / "b.csv"],
        ["bench", f["graph"], "-i", f["rec"], "--knob", "k.k=1,2", "--plot", ro / "b.png"],
        ["scene", "plan", SCENE, "-o", ro / "plan.yaml"],
        ["scene", "plan", SCENE, "-o", tmp_path / "plan.yaml", "--json", ro / "plan.json"],
        ["scene", "run", SCENE, "-i", f["rec"], "-o", ro / "o.npz"],
        ["live", f["graph"], "--dbc", DBC, "--map", MAP, "--stats", ro / "stats.json"],
        ["live", f["graph"], "--dbc", DBC, "--map", MAP, "--record", ro / "s.blf"],
        ["resample", f["rec"], "--rate", "500", "-o", ro / "r.npz"],
        ["models", "resample", f["models"], "--rate", "500", "-o", ro / "m.json"],
        ["plot", f["rec"], "-o", ro / "p.png"],
        ["compare", f["models"], f["rec"], "--speed", "speed", "--json", ro / "c.json"],
    ]
    for argv in cases:
        code, err = _run(capsys, argv)
        assert code == 1 and len(err) == 1, (argv, err)
        assert f"folder {ro} is not writable" in err[0], (argv, err)
    assert list(ro.iterdir()) == []
    assert not (tmp_path / "s.json").exists() and not (tmp_path / "plan.yaml").exists()


def test_missing_folders_are_created_the_same_way_by_every_verb(files, capsys, tmp_path):
    out = tmp_path / "a" / "b" / "r.npz"
    assert main(["resample", str(files["rec"]), "--rate", "500", "-o", str(out)]) == 0
    assert out.exists()
    rng = np.random.default_rng(1)
    n_force = rng.uniform(0.5, 2.0, 500)
    save_recording(tmp_path / "fr.npz", {"fn": n_force, "ft": 0.4 * n_force + 0.01 * rng.normal(size=500)}, rate=1000.0)
    mu = tmp_path / "c" / "d" / "mu.json"
    assert main(["fit", "friction", str(tmp_path / "fr.npz"), "--force", "fn", "--friction-force", "ft", "-o", str(mu)]) == 0
    assert mu.exists()
    capsys.readouterr()


def test_plot_onto_its_own_input_is_refused(files, capsys):
    before = files["rec"].read_bytes()
    code, err = _run(capsys, ["plot", files["rec"], "-o", files["rec"]])
    assert code == 1 and "that is an input" in err[0] and files["rec"].read_bytes() == before


def test_fit_texture_xml_onto_a_folder_and_report_onto_a_file_fail_before_the_fit(files, capsys, tmp_path):
    out = tmp_path / "s.json"
    (tmp_path / "xmldir").mkdir()
    code, err = _run(capsys, ["fit", "texture", files["rec"], "--speed", "speed", "-o", out, "--xml", tmp_path / "xmldir"])
    assert code == 1 and err == [f"--xml {tmp_path / 'xmldir'}: is a folder; give a file name inside it"]
    (tmp_path / "report.txt").write_text("mine\n")
    code, err = _run(capsys, ["fit", "texture", files["rec"], "--speed", "speed", "-o", out, "--report", tmp_path / "report.txt"])
    assert code == 1 and len(err) == 1 and err[0].startswith(f"--report {tmp_path / 'report.txt'}: is a file")
    assert not out.exists() and (tmp_path / "report.txt").read_text() == "mine\n"


@pytest.mark.parametrize("verb, option", [("fit", "-o"), ("fit", "--xml"), ("fit", "--holdout-json"), ("compare", "--json")])
def test_a_report_folder_named_as_another_output_fails_before_the_work(files, capsys, tmp_path, verb, option):
    # `fit texture -o s.json --report s.json` made a folder s.json, fitted, then failed writing -o: exit 2, folder left
    same = tmp_path / ("s.xml" if option == "--xml" else "s.json")
    if verb == "fit":
        extra = ["--holdout", "0.3"] if option == "--holdout-json" else []
        out = [] if option == "-o" else ["-o", tmp_path / "fit.json"]
        argv = ["fit", "texture", files["rec"], "--speed", "speed", *extra, *out, option, same, "--report", same]
    else:
        argv = ["compare", files["models"], files["rec"], "--speed", "speed", option, same, "--report", same]
    code, err = _run(capsys, argv)
    assert code == 1 and err == [f"--report {same}: {option} writes that file; give the report a folder of its own"], err
    assert not same.exists() and not (tmp_path / "fit.json").exists()


def test_two_outputs_of_one_command_on_one_file_fail_before_the_work(files, capsys, tmp_path):
    # `fit texture -o s.json --holdout 0.3 --holdout-json s.json` wrote the surface, then the held-out figures over it,
    # exit 0: the surface was lost. `bench -o t.png --plot t.png` drew the plot over the table. Files not yet written
    # were compared by name only when they existed.
    same = tmp_path / "sub" / ".." / "s.json"
    code, err = _run(capsys, ["fit", "texture", files["rec"], "--speed", "speed", "--holdout", "0.3", "-o", tmp_path / "s.json",
                              "--holdout-json", same])
    assert code == 1 and err == [f"--holdout-json {same}: -o writes that file too; give each output its own file"], err
    assert not (tmp_path / "s.json").exists()
    code, err = _run(capsys, ["bench", files["graph"], "-i", files["rec"], "--knob", "k.k=1,2", "-o", tmp_path / "t.csv",
                              "--plot", tmp_path / "t.csv"])
    assert code == 1 and len(err) == 1 and err[0].startswith(f"--plot {tmp_path / 't.csv'}: "), err  # a table is no plot
    # bench's -o writes CSV whatever the name said (a table in t.png, which --plot t.png then drew over): CSV names only
    code, err = _run(capsys, ["bench", files["graph"], "-i", files["rec"], "--knob", "k.k=1,2", "-o", tmp_path / "t.png",
                              "--plot", tmp_path / "t.png"])
    assert code == 1 and err == [f"-o {tmp_path / 't.png'}: unknown output format '.png'; use .csv"], err
    assert not (tmp_path / "t.png").exists() and not (tmp_path / "t.csv").exists()


def test_fit_friction_into_a_missing_model_set_fails_before_writing_o(files, capsys, tmp_path):
    rng = np.random.default_rng(1)
    n_force = rng.uniform(0.5, 2.0, 500)
    save_recording(tmp_path / "fr.npz", {"fn": n_force, "ft": 0.4 * n_force + 0.01 * rng.normal(size=500)}, rate=1000.0)
    out = tmp_path / "mu.json"
    code, err = _run(capsys, ["fit", "friction", tmp_path / "fr.npz", "--force", "fn", "--friction-force", "ft", "-o", out,
                              "--into", tmp_path / "missing.json"])
    assert code == 1 and len(err) == 1 and "missing.json" in err[0] and not out.exists()


def test_into_keeps_the_model_sets_mode_and_new_files_follow_the_umask(files, capsys, tmp_path):
    rng = np.random.default_rng(1)
    n_force = rng.uniform(0.5, 2.0, 500)
    save_recording(tmp_path / "fr.npz", {"fn": n_force, "ft": 0.4 * n_force + 0.01 * rng.normal(size=500)}, rate=1000.0)
    files["models"].chmod(0o640)
    old = os.umask(0o027)
    try:
        assert main(["fit", "friction", str(tmp_path / "fr.npz"), "--force", "fn", "--friction-force", "ft",
                     "-o", str(tmp_path / "mu.json"), "--into", str(files["models"])]) == 0
        assert main(["resample", str(files["rec"]), "--rate", "500", "-o", str(tmp_path / "r.csv")]) == 0
    finally:
        os.umask(old)
    capsys.readouterr()
    assert stat.S_IMODE(files["models"].stat().st_mode) == 0o640  # --into: the file's own mode
    assert stat.S_IMODE((tmp_path / "mu.json").stat().st_mode) == 0o640  # 0666 & ~0027
    assert stat.S_IMODE((tmp_path / "r.csv").stat().st_mode) == 0o640
    assert not [p for p in tmp_path.iterdir() if ".part" in p.name]  # no temporary file left behind


def test_an_unknown_output_format_is_refused_before_the_work(files, capsys, tmp_path):
    for argv in (["run", files["graph"], "--input", files["rec"], "-o", tmp_path / "o.xyz"],
                 ["resample", files["rec"], "--rate", "500", "-o", tmp_path / "o.xyz"],
                 ["scene", "run", SCENE, "-i", files["rec"], "-o", tmp_path / "o.xyz"]):
        code, err = _run(capsys, argv)
        assert code == 1 and len(err) == 1, err  # run and resample also write .wav (audio-rate outputs)
        assert err[0].startswith(f"-o {tmp_path / 'o.xyz'}: unknown output format '.xyz'; use .npz, .csv, .h5, .hdf5"), err


PLUGIN = '''
import numpy as np
from numba import njit
from flowtex.node_api import Node, NodeState, Param, Port


@njit(cache=True)
def table_shift_kernel(p, s, si, x, y):
    for t in range(x.shape[0]):
        y[t, 0] = x[t, 0] + p[0]


class TableShift(Node):
    """Adds a number read from a file of the plugin's own (a path parameter no flowtex reader reads)."""

    type_name = "table_shift"
    params = {"table": Param("path", doc="a text file holding one number")}
    inputs = {"x": Port((), "*", "signal")}
    outputs = {"y": Port("=x", "=x", "shifted signal")}
    kernel = table_shift_kernel

    def build(self, inputs, outputs):
        return NodeState(params=np.array([float(open(self.p["table"]).read().split()[-1])]))
'''

SHIFT_GRAPH = """flowtex: 1
name: shift
rate: 1000
inputs:
  x: {unit: N}
nodes:
  shift: {type: table_shift, params: {table: table.csv}}
edges:
  - x -> shift.x
outputs:
  y: shift.y
"""


@pytest.fixture(scope="module")
def plugs(tmp_path_factory):
    """One plugin folder for the module's tests: a second copy of it loaded in the same process would be a module of
    its own, filed by its path (flowtex.registry), and compile its kernel again at every run of the suite."""
    folder = tmp_path_factory.mktemp("plugs")
    (folder / "shift.py").write_text(PLUGIN)
    return folder


@pytest.mark.parametrize("how", ["graph file", "--set"])
def test_an_output_that_a_node_of_the_graph_reads_is_refused_before_the_run(tmp_path, plugs, capsys, monkeypatch, how):
    """A path parameter names a file the graph reads (here a plugin's table, which -o can name as a CSV); writing the
    outputs over it would lose it. Refused once the graph is checked, before the compile and the run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "g.yaml").write_text(SHIFT_GRAPH if how == "graph file" else SHIFT_GRAPH.replace("table.csv", "other.csv"))
    save_recording(tmp_path / "in.npz", {"x": np.arange(100.0)}, rate=1000.0)
    victim = tmp_path / "table.csv"
    victim.write_text("# rate: 1000\nx\n2.5\n")
    before = victim.read_bytes()
    argv = ["run", "g.yaml", "--plugins", plugs, "--input", "in.npz", "-o", "table.csv"]
    code, err = _run(capsys, argv + (["--set", "shift.table=table.csv"] if how == "--set" else []))
    err = [line for line in err if not line.startswith("flowtex: loaded plugin code")]
    assert code == 1 and err == [f"-o table.csv: that is a file the graph reads ({victim}); flowtex never overwrites an "
                                 "input: choose another output file"], err
    assert victim.read_bytes() == before and sorted(os.listdir(tmp_path)) == ["g.yaml", "in.npz", "table.csv"]


def test_watch_plot_over_a_file_the_graph_reads_is_refused_and_the_file_kept(tmp_path, plugs, capsys, monkeypatch):
    """watch --plot PNG named like a file a node reads (here the plugin's table) would be redrawn over it at every run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "g.yaml").write_text(SHIFT_GRAPH.replace("table.csv", "shot.png"))
    save_recording(tmp_path / "in.npz", {"x": np.arange(100.0)}, rate=1000.0)
    victim = tmp_path / "shot.png"
    victim.write_text("2.5\n")
    code = main(["watch", "g.yaml", "--plugins", str(plugs), "-i", "in.npz", "--plot", "shot.png", "--max-runs", "1"])
    out = capsys.readouterr().out
    assert code == 1 and f"--plot shot.png: that is a file the graph reads ({victim})" in out, out
    assert victim.read_text() == "2.5\n"


def test_live_stats_over_the_model_set_the_graph_reads_is_refused_before_the_session(files, capsys, tmp_path):
    """--stats STATS.json named like the graph's model set (a JSON file too) would replace the models with statistics."""
    graph = tmp_path / "live.yaml"
    graph.write_text((REPO / "graphs" / "live_texture.yaml").read_text().replace("data/synthetic_texture.json", "m.json"))
    save_recording(tmp_path / "sim.npz", {"position": np.zeros((200, 3)), "normal_force": np.ones(200)}, rate=1000.0)
    before = files["models"].read_bytes()
    code, err = _run(capsys, ["live", graph, "--dbc", DBC, "--map", MAP, "--simulate", tmp_path / "sim.npz",
                              "--duration", "0.1", "--quiet", "--stats", files["models"]])
    assert code == 1 and len(err) == 1 and err[0].startswith(f"--stats {files['models']}: that is a file the graph reads"), err
    assert files["models"].read_bytes() == before


@pytest.mark.parametrize("option,victim,knob", [
    ("-o", "table.csv", ["--knob", "shift.table=other.csv,table.csv"]),
    ("--plot", "shot.png", ["--knob", "shift.table=other.csv,shot.png"]),
    ("-o", "table.csv", ["--knob", "shift.every=1,2", "--set", "shift.table=table.csv"]),
    ("-o", "table.csv", ["--knob", "shift.table=other.csv,two.csv", "--reference", "shift.table=table.csv"])])
def test_bench_output_over_a_file_a_knob_makes_the_graph_read_is_refused(tmp_path, plugs, capsys, monkeypatch, option, victim, knob):
    """A knob names a file only some configurations read (the plugin's table): bench -o/--plot checked only the graph
    and the recording, so the sweep would write its table or plot over that file. Every configuration's reads are checked
    before anything runs; the line names the option, the knob and the file."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "g.yaml").write_text(SHIFT_GRAPH.replace("table.csv", "other.csv"))
    (tmp_path / "other.csv").write_text("1.5\n")
    (tmp_path / "two.csv").write_text("2\n")
    save_recording(tmp_path / "in.npz", {"x": np.arange(100.0)}, rate=1000.0)
    (tmp_path / victim).write_text("2.5\n")
    before = sorted(os.listdir(tmp_path))
    code, err = _run(capsys, ["bench", "g.yaml", "--plugins", plugs, "-i", "in.npz", *knob, option, victim])
    err = [line for line in err if not line.startswith("flowtex: loaded plugin code")]
    given = next((k for k in ("--set", "--reference") if k in knob), "--knob")
    via = f"{given} shift.table={victim}"
    assert code == 1 and err == [f"{option} {victim}: that is a file the graph reads with {via} ({tmp_path / victim}); "
                                 "flowtex never overwrites an input: choose another output file"], err
    assert (tmp_path / victim).read_text() == "2.5\n" and sorted(os.listdir(tmp_path)) == before
