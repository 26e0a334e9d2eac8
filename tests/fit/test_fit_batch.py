"""Many surfaces on Dask: a LocalCluster of 2 processes gives the same files as a serial run."""

from __future__ import annotations

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
