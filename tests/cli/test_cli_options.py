"""One flag vocabulary, numeric ranges refused with the range, plugins announced and skippable, text from files
escaped, and the layering (issue 17). Cases that fail stop before any fit or compile."""

from __future__ import annotations

import ast
import re
import shutil
from pathlib import Path

import numpy as np
import pytest

from flowtex.cli import build_parser, main
from flowtex.datasets.model_sets import synthetic_model_set
from flowtex.io.modelset import save_model_set
from flowtex.io.recordings import load_recording, save_recording
from tests.cli.gain_graph import GAIN_GRAPH as GRAPH
from tests.conftest import REPO


@pytest.fixture
def rec(tmp_path):
    rng = np.random.default_rng(0)
    n = 2000
    path = tmp_path / "in.npz"
    save_recording(path, {"x": rng.normal(size=n), "accel": rng.normal(size=n), "speed": np.full(n, 100.0),
                          "normal_force": np.full(n, 1.0)}, rate=1000.0)
    return path


def _err(capsys, argv) -> list[str]:
    code = main([str(a) for a in argv])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 1, err
    return err


def test_numeric_options_are_refused_with_their_valid_range(rec, tmp_path, capsys):
    out = tmp_path / "o.json"
    texture = ["fit", "texture", rec, "--speed", "speed", "-o", out]
    cases = [
        (["resample", rec, "--rate", "1e12", "-o", tmp_path / "r.npz"], "argument --rate: 1e12 is out of range: valid (0, 1e+06] Hz"),
        (["resample", rec, "--rate", "1e5", "-o", tmp_path / "r.npz"],
         "--rate 100000: valid range for this 1000 Hz recording is 15.625 to 64000 Hz"),
        (texture + ["--from-rate", "1e12"], "argument --from-rate: 1e12 is out of range: valid (0, 1e+06] Hz"),
        (texture + ["--highpass", "600"], "--highpass 600: valid range is 0 (none) to below 500 Hz"),
        (texture + ["--highpass", "-5"], "argument --highpass: -5 is out of range: valid [0, inf) Hz"),
        (texture + ["--render-rate", "1e9"], "argument --render-rate: 1e9 is out of range: valid (0, 1e+06] Hz"),
        (texture + ["--render-rate", "1e5"], "--render-rate 100000: valid range for this 1000 Hz recording is 62.5 to 16000 Hz"),
        (["fit", "taps", rec, "--accel", "accel", "--force", "normal_force", "--speed", "speed", "--length", "-0.1", "-o", out],
         "argument --length: -0.1 is out of range: valid (0, 10] s"),
        (["fit", "friction", rec, "--force", "normal_force", "--friction-force", "x", "--min-force", "-1", "-o", out],
         "argument --min-force: -1 is out of range: valid [0, inf) N"),
        (["bench", tmp_path / "g.yaml", "-i", rec, "--knob", "k.k=1,2", "--repeats", "0"],
         "argument --repeats: 0 is out of range: valid 1..1000"),
        (["models", "resample", tmp_path / "m.json", "--rate", "1e9", "-o", out], "argument --rate: 1e9 is out of range: valid (0, 1e+06] Hz"),
        (["models", "resample", tmp_path / "m.json", "--rate", "1e5", "-o", out],
         "--rate 100000: valid range for this 1000 Hz model set is 62.5 to 16000 Hz"),
        (["models", "resample", tmp_path / "m.json", "--rate", "2000", "--extra-order", "1000", "-o", out],
         "argument --extra-order: 1000 is out of range: valid 0..20"),
    ]
    save_model_set(synthetic_model_set([60.0], [0.5], ar_order=4, ma_order=2), tmp_path / "m.json")
    for argv, message in cases:
        err = _err(capsys, argv)
        assert len(err) == 1 and message in err[0], (argv, err)
    assert not out.exists()


def test_nonfinite_pass_works_from_the_command_line(tmp_path, capsys):
    (tmp_path / "g.yaml").write_text(GRAPH)
    x = np.arange(50, dtype=np.float64)
    x[7] = np.nan
    save_recording(tmp_path / "in.npz", {"x": x}, rate=1000.0)
    out = tmp_path / "o.npz"
    assert main(["run", str(tmp_path / "g.yaml"), "-i", str(tmp_path / "in.npz"), "-o", str(out), "--no-plugins",
                 "--nonfinite", "pass"]) == 0
    capsys.readouterr()
    np.testing.assert_array_equal(load_recording(out).arrays["y"], 2.0 * x)  # the NaN passed through, unchanged


def test_old_spellings_work_with_a_one_line_notice(tmp_path, capsys):
    rng = np.random.default_rng(1)
    fn = rng.uniform(0.5, 2.0, 500)
    ft = 0.4 * fn + 0.01 * rng.normal(size=500)
    f3 = np.stack([ft, np.zeros(500), -fn], axis=1)  # tangential along x, pressing down -z
    save_recording(tmp_path / "fr.npz", {"fn": fn, "ft": ft, "f3": f3})  # states no rate
    mus = []
    for k, argv in enumerate((["--force", "fn", "--friction-force", "ft", "--from-rate", "1000"],
                              ["--normal-force", "fn", "--friction-force", "ft", "--rate", "1000"],
                              ["--force3", "f3", "--normal", "0,0,1", "--from-rate", "1000"],
                              ["--force", "f3", "--normal", "0,0,1", "--from-rate", "1000"])):
        out = tmp_path / f"mu{k}.json"
        assert main(["fit", "friction", str(tmp_path / "fr.npz"), *argv, "-o", str(out)]) == 0
        notices = [line for line in capsys.readouterr().err.splitlines() if line.startswith("notice:")]
        mus.append(__import__("json").loads(out.read_text())["mu"])
        if k == 1:
            assert notices == ["notice: --normal-force is now spelled --force (the normal force in N); the old spelling still works",
                               "notice: --rate is now spelled --from-rate (the recording's rate); the old spelling still works"]
        elif k == 3:
            assert notices == ["notice: --force with --normal is the old spelling of --force3 (a 3-axis force); read as --force3"]
        else:
            assert notices == []
    # the same forces, so the same mu (0.4 by construction) whichever spelling named them
    assert mus[0] == mus[1] and mus[2] == mus[3]
    assert mus[0] == pytest.approx(0.4, abs=0.01) and mus[2] == pytest.approx(mus[0], rel=1e-9)


def test_rate_flags_mean_one_thing_each():
    parse = build_parser().parse_args
    assert parse(["resample", "a.npz", "--rate", "500", "--from-rate", "1000", "-o", "b.npz"]).from_rate == 1000.0
    assert parse(["fit", "taps", "a.npz", "--accel", "a", "--force", "f", "--from-rate", "800", "-o", "t.json"]).from_rate == 800.0
    args = parse(["fit", "texture", "a.npz", "--force", "F", "-o", "s.json"])
    assert args.force == "F" and args.from_rate is None


def test_bench_and_scene_live_accept_set():
    parse = build_parser().parse_args
    assert parse(["bench", "g.yaml", "-i", "r.npz", "--knob", "k.k=1,2", "--set", "k.k=3"]).overrides == ["k.k=3"]
    assert parse(["scene", "live", "s.yaml", "--set", "a.b=1", "--no-plugins"]).overrides == ["a.b=1"]
    assert parse(["scene", "run", "s.yaml", "-i", "r.npz", "--set", "a.b=1"]).overrides == ["a.b=1"]


def test_a_graph_name_with_escape_codes_is_printed_escaped(tmp_path, capsys):
    (tmp_path / "g.yaml").write_text(GRAPH.replace("name: g", 'name: "\\e[31mred\\e[0m\\a"'))
    assert main(["graph", str(tmp_path / "g.yaml"), "--no-plugins", "--dot"]) == 0
    out = capsys.readouterr()
    assert "\x1b" not in out.out + out.err and "\a" not in out.out + out.err
    assert "\\x1b[31mred" in out.out


def test_plugins_are_announced_and_no_plugins_skips_the_graph_folders(tmp_path, capsys, monkeypatch):
    (tmp_path / "elsewhere").mkdir()
    monkeypatch.chdir(tmp_path / "elsewhere")  # only the graph folder's plugins/ is loaded
    (tmp_path / "plugins").mkdir()
    shutil.copy(REPO / "plugins" / "soft_clip.py", tmp_path / "plugins" / "soft_clip.py")
    (tmp_path / "g.yaml").write_text(GRAPH.replace("{type: gain, params: {k: 2}}", "{type: soft_clip, params: {limit: 1}}"))
    assert main(["validate", str(tmp_path / "g.yaml")]) == 0
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"flowtex: loaded plugin code: {tmp_path / 'plugins' / 'soft_clip.py'} (skip the automatic ones with --no-plugins)"]
    err = _err(capsys, ["validate", tmp_path / "g.yaml", "--no-plugins"])
    assert len(err) == 1 and "unknown node type 'soft_clip'" in err[0]
    # an explicit --plugins DIR is still loaded (and announced) with --no-plugins
    assert main(["validate", str(tmp_path / "g.yaml"), "--no-plugins", "--plugins", str(tmp_path / "plugins")]) == 0
    assert "loaded plugin code" in capsys.readouterr().err


def test_a_bad_command_line_is_one_line_and_exit_1(capsys):
    err = _err(capsys, ["fit", "texture", "--order"])
    assert len(err) == 1 and err[0].startswith("flowtex fit texture: argument --order: expected one argument")


def test_nothing_below_the_cli_imports_it_or_argparse():
    root = REPO / "flowtex"
    offenders = []
    for path in root.rglob("*.py"):
        if (root / "cli") in path.parents or path == root / "__main__.py":  # the entry point sits above the CLI
            continue
        text = path.read_text(encoding="utf-8")
        if "argparse" not in text and not re.search(r"\bcli\b", text):
            continue  # every import this test looks for names one of the two: no need to parse the file
        for node in ast.walk(ast.parse(text)):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else []
            if isinstance(node, ast.ImportFrom):
                names = [("." * node.level) + (node.module or "")]
            for name in names:
                if name == "argparse" or name.startswith("flowtex.cli") or name.lstrip(".") == "cli" or ".cli." in name:
                    offenders.append(f"{Path(path).relative_to(REPO)}: {name}")
    assert offenders == []


def test_bench_on_an_empty_recording_is_one_line(tmp_path, capsys):
    (tmp_path / "g.yaml").write_text(GRAPH)
    np.savez(tmp_path / "zero.npz", x=np.zeros(0), rate=np.float64(1000.0))
    err = _err(capsys, ["bench", tmp_path / "g.yaml", "-i", tmp_path / "zero.npz", "--knob", "k.k=1,2"])
    # the reader may refuse it first (an empty recording); either way one line naming the file
    assert len(err) == 1 and err[0].startswith(f"{tmp_path / 'zero.npz'}: ") and "internal error" not in err[0], err
