"""Where plugin code comes from: never the current folder; the graph's own folders, --plugins, $FLOWTEX_PLUGINS (issue 27 §5)."""

from __future__ import annotations

import shutil
from pathlib import Path

from flowtex.cli import main

REPO = Path(__file__).resolve().parents[1]

GRAPH = """\
flowtex: 1
name: t
rate: 1000
{plugins}inputs: {{x: {{}}}}
nodes:
  c: {{type: soft_clip, params: {{limit: 1.0}}}}
edges: [x -> c.x]
outputs: {{y: c.y}}
"""


def _err(capsys) -> list[str]:
    return capsys.readouterr().err.strip().splitlines()


def test_the_current_folders_plugins_are_not_imported(tmp_path, monkeypatch, capsys):
    (tmp_path / "plugins").mkdir()
    marker = tmp_path / "ran"
    (tmp_path / "plugins" / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\n")
    shutil.copy(REPO / "plugins" / "soft_clip.py", tmp_path / "plugins" / "soft_clip.py")
    graphs = tmp_path / "graphs"
    graphs.mkdir()
    (graphs / "g.yaml").write_text(GRAPH.format(plugins=""))
    monkeypatch.chdir(tmp_path)
    assert main(["validate", "graphs/g.yaml"]) == 1
    assert "unknown node type 'soft_clip'" in _err(capsys)[-1]
    assert main(["nodes"]) == 0
    capsys.readouterr()
    assert not marker.exists()


def test_the_plugins_key_names_folders_relative_to_the_graph(tmp_path, monkeypatch, capsys):
    (tmp_path / "lib").mkdir()
    shutil.copy(REPO / "plugins" / "soft_clip.py", tmp_path / "lib" / "soft_clip.py")
    (tmp_path / "graphs").mkdir()
    (tmp_path / "graphs" / "g.yaml").write_text(GRAPH.format(plugins="plugins: [../lib]\n"))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    assert main(["validate", str(tmp_path / "graphs" / "g.yaml")]) == 0
    err = _err(capsys)
    assert err == [f"flowtex: loaded plugin code: {tmp_path / 'lib' / 'soft_clip.py'} (skip the automatic ones with --no-plugins)"]
    assert main(["validate", str(tmp_path / "graphs" / "g.yaml"), "--no-plugins"]) == 1  # graph-provided code is skipped
    assert "unknown node type 'soft_clip'" in _err(capsys)[-1]


def test_a_missing_plugins_folder_is_reported_at_its_line(tmp_path, capsys):
    (tmp_path / "g.yaml").write_text(GRAPH.format(plugins="plugins:\n  - ../nowhere\n"))
    assert main(["validate", str(tmp_path / "g.yaml")]) == 1
    err = _err(capsys)
    assert len(err) == 1 and err[0].startswith(f"{tmp_path / 'g.yaml'}:5:5: plugins: folder '../nowhere' does not exist")
    (tmp_path / "g.yaml").write_text(GRAPH.format(plugins="plugins: ../lib\n"))
    assert main(["validate", str(tmp_path / "g.yaml")]) == 1
    assert "plugins must be a list of folders" in _err(capsys)[0]


def test_the_bundled_actuator_graph_finds_its_plugin_from_anywhere(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    assert main(["validate", str(REPO / "graphs" / "actuator_drive.yaml")]) == 0
    assert "soft_clip.py" in capsys.readouterr().err


def test_a_plugin_calling_sys_exit_is_reported(tmp_path, capsys):
    (tmp_path / "plugins").mkdir()
    (tmp_path / "plugins" / "quits.py").write_text("import sys\n\nsys.exit(0)\n")
    (tmp_path / "g.yaml").write_text(GRAPH.format(plugins=""))
    assert main(["validate", str(tmp_path / "g.yaml")]) == 1
    err = _err(capsys)
    assert err == [f"{tmp_path / 'plugins' / 'quits.py'}:3: plugin called sys.exit(0) while being imported; a plugin file "
                   "must only define node types (flowtex stopped, nothing done)"]
