"""Many surfaces on Dask: a local cluster (--workers) and an existing scheduler (--scheduler) give the same files as a serial run."""

from __future__ import annotations

import pytest

from flowtex.cli import main
from flowtex.datasets import free_exploration


def test_dask_matches_serial(tmp_path, capsys):
    # two tiny recordings (4 s each, fixed order: the point here is the plumbing, not the fit)
    for seed in (1, 2):
        free_exploration(4.0, 1000.0, seed=seed, plateau_s=(1.5, 2.0)).save(tmp_path / "in" / f"surface{seed}.npz")
    common = [str(tmp_path / "in"), "--speed", "speed", "--order", "4,2"]
    assert main(["fit", "texture", *common, "--out-dir", str(tmp_path / "serial"), "--workers", "0"]) == 0
    assert main(["fit", "texture", *common, "--out-dir", str(tmp_path / "dask"), "--workers", "2"]) == 0
    printed = capsys.readouterr().out
    assert "2 of 2 surfaces" in printed
    for seed in (1, 2):
        serial = (tmp_path / "serial" / f"surface{seed}.json").read_text()
        assert serial == (tmp_path / "dask" / f"surface{seed}.json").read_text()  # same machine: same bits


def test_existing_scheduler_matches_serial(tmp_path, capsys):
    # --scheduler: a real dask.distributed cluster started here (one worker process); its scheduler runs in this
    # process, so the test sees that the fits ran on it, and the files must equal a serial run's (same machine)
    from distributed import LocalCluster

    free_exploration(4.0, 1000.0, seed=3, plateau_s=(1.5, 2.0)).save(tmp_path / "in" / "surface3.npz")
    common = [str(tmp_path / "in"), "--speed", "speed", "--order", "4,2"]
    assert main(["fit", "texture", *common, "--out-dir", str(tmp_path / "serial"), "--workers", "0"]) == 0
    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=None) as cluster:
        assert main(["fit", "texture", *common, "--out-dir", str(tmp_path / "remote"), "--scheduler", cluster.scheduler_address]) == 0
        prefix = cluster.scheduler.task_prefixes.get("fit_one")
        assert prefix is not None and prefix.state_counts["memory"] + prefix.state_counts["released"] + prefix.state_counts["forgotten"] >= 1
    assert "1 of 1 surfaces" in capsys.readouterr().out
    assert (tmp_path / "serial" / "surface3.json").read_text() == (tmp_path / "remote" / "surface3.json").read_text()


def test_grid_index(tmp_path, capsys):
    """Romano-2012 grid: one stationary recording per (speed, force) cell, labelled with the index's nominal values."""
    import numpy as np

    from flowtex.datasets import default_surface, render_texture
    from flowtex.io.modelset import load_model_set
    from flowtex.io.recordings import save_recording

    truth = default_surface()
    rows = ["file,speed,force"]
    cells = [(60.0, 0.8), (60.0, 2.4), (250.0, 0.8), (250.0, 2.4)]
    acc = render_texture(truth, np.repeat([c[0] for c in cells], 2000), np.repeat([c[1] for c in cells], 2000), 1000.0)  # one compile
    for k, (s, f) in enumerate(cells):
        save_recording(tmp_path / f"cell{k}.npz", {"accel": acc[2000 * k:2000 * (k + 1)]}, 1000.0)
        rows.append(f"cell{k}.npz,{s},{f}")
    (tmp_path / "index.csv").write_text("\n".join(rows) + "\n")
    out = tmp_path / "grid.json"
    assert main(["fit", "texture", "--grid", str(tmp_path / "index.csv"), "--order", "6,4", "-o", str(out)]) == 0
    ms = load_model_set(out)
    measured = ms.variance > 0
    assert sorted(zip(ms.speeds[measured], ms.forces[measured], strict=True)) == [(60.0, 0.8), (60.0, 2.4), (250.0, 0.8), (250.0, 2.4)]
    assert ms.max_speed == 250.0 and ms.max_force == 2.4
    capsys.readouterr()


def test_recordings_that_would_share_an_output_file_are_refused_before_any_fit(tmp_path, capsys, monkeypatch):
    """a/rec.npz and b/rec.npz both went to OUT/rec.json: the second replaced the first, and '2 of 2 surfaces' was said.
    One file named twice (a path and a glob that covers it, sub/../rec.npz) is one recording, fitted once."""
    import numpy as np

    import flowtex.fit.batch as batch
    from flowtex.io.recordings import save_recording

    for folder in ("a", "b"):
        save_recording(tmp_path / folder / "rec.npz", {"accel": np.zeros(10), "speed": np.ones(10)}, rate=1000.0)
    monkeypatch.setattr(batch, "fit_one", lambda *a, **k: pytest.fail("a fit started"))
    a, b, out = tmp_path / "a" / "rec.npz", tmp_path / "b" / "rec.npz", tmp_path / "out"
    assert main(["fit", "texture", str(a), str(b), "--speed", "speed", "--out-dir", str(out), "--workers", "0"]) == 1
    assert capsys.readouterr().err.strip() == (f"--out-dir {out}: {a} and {b} would both be written to {out / 'rec.json'}; "
                                               "rename one, or fit them into separate --out-dir folders")
    assert batch.expand_inputs([str(a), str(tmp_path / "b" / ".." / "a" / "rec.npz"), str(tmp_path / "a" / "*.npz")]) == [a]


def test_out_dir_writes_each_report_into_the_report_folder_given(tmp_path, monkeypatch, capsys):
    """--out-dir OUT --report DIR wrote every report to OUT/<stem>_report and ignored DIR; --xml FILE.xml was ignored
    too. Now the reports go to DIR/<stem>_report, and a file name for --xml is refused before any fit (the fit is
    replaced here: the point is where things are written)."""
    import flowtex.fit.report as report
    import flowtex.fit.texture_job as texture_job

    (tmp_path / "in").mkdir()
    for name in ("a", "b"):
        (tmp_path / "in" / f"{name}.npz").write_bytes(b"")
    written: list = []
    monkeypatch.setattr(texture_job, "fit_recording", lambda path, job: path.stem)
    monkeypatch.setattr(texture_job, "write_outputs", lambda fit, out, xml, *a: written.append((out, xml)))
    monkeypatch.setattr(report, "write_report", lambda fit, folder, *a, **k: written.append(folder))
    monkeypatch.setattr(report, "summary_line", lambda fit: f"fitted {fit}")
    monkeypatch.setattr(report, "edge_warning", lambda fit: None)
    common = ["fit", "texture", str(tmp_path / "in"), "--speed", "speed", "--out-dir", str(tmp_path / "out"), "--workers", "0"]
    assert main([*common, "--report", str(tmp_path / "reports")]) == 0
    assert sorted(w for w in written if not isinstance(w, tuple)) == [tmp_path / "reports" / "a_report",
                                                                     tmp_path / "reports" / "b_report"]
    written.clear()
    assert main([*common, "--xml", str(tmp_path / "x.xml")]) == 1
    assert "--xml" in capsys.readouterr().err and written == []
    assert main([*common, "--xml"]) == 0
    assert sorted(xml for out, xml in written) == [tmp_path / "out" / "a.xml", tmp_path / "out" / "b.xml"]
