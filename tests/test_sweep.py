import csv

import pytest

from dfa_model import preset
from dfa_model.cli import main
from dfa_model.sweep import grid, run, run_case

SETTINGS = dict(voltage=6000, force=5.0, duration=2.0)


def test_grid_is_a_cartesian_product():
    cases = grid(preset("vshape-table1"), SETTINGS, rho_l=[2e12, 3e12], force=[3, 5, 7])
    assert len(cases) == 6
    assert cases[0].varied == {"rho_l": 2e12, "force": 3} and cases[0].settings["force"] == 3
    with pytest.raises(ValueError, match="apex: cannot be varied"):
        grid(preset("vshape-table1"), SETTINGS, apex=[1])


def test_failing_case_is_reported_and_others_kept():
    cases = grid(preset("vshape-table1").replace(N=41), SETTINGS, a=[0.0119, 0.06, 0.011])
    rows = run(cases, max_workers=2, progress=False)
    assert [r["status"] for r in rows] == ["ok", "error", "ok"]
    assert rows[1]["label"] == "a=0.06" and "semi-aperture" in rows[1]["error"]
    assert rows[0]["unzipping_speed"] > 0 and rows[2]["unzipping_speed"] > 0


def test_sweep_matches_direct_runs():
    cases = grid(preset("vshape-table1").replace(N=41), SETTINGS, theta0=[20.0, 30.0])
    rows = run(cases, max_workers=2, progress=False)
    direct = [run_case(c) for c in cases]
    for a, b in zip(rows, direct):
        assert a["unzipping_speed"] == b["unzipping_speed"]
    assert rows[1]["unzipping_speed"] > rows[0]["unzipping_speed"]


def test_dask_local_cluster():
    distributed = pytest.importorskip("dask.distributed")
    cases = grid(preset("vshape-table1").replace(N=41), SETTINGS, rho_l=[2e12, 3e12], a=[0.0119, 0.06])
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cl:
        with distributed.Client(cl) as client:
            rows = run(cases, executor=client.get_executor(), progress=False)
    assert [r["status"] for r in rows] == ["ok", "error", "ok", "error"]
    assert rows[2]["unzipping_speed"] < rows[0]["unzipping_speed"]     # higher rho_l: slower


def test_cli_sweep_writes_csv_and_flags_failures(tmp_path, capsys):
    out = tmp_path / "s.csv"
    rc = main(["sweep", "--preset", "vshape-table1", "--set", "N=41", "--voltage", "6000", "--force", "5",
               "--duration", "1", "--vary", "rho_l=2e12,2.5e12", "--vary", "a=0.0119,0.06", "--workers", "2",
               "--quiet", "--out", str(out)])
    assert rc == 1                                       # one variant failed, the others are kept
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 4 and sum(r["status"] == "ok" for r in rows) == 2
    assert "2 of 4 runs failed" in capsys.readouterr().err
