import csv
import json
import subprocess
import sys

import pytest

from dfa_model import load
from dfa_model.cli import main


def run(args, capsys):
    rc = main(args)
    out = capsys.readouterr()
    return rc, out.out, out.err


def test_params_prints_a_loadable_preset(tmp_path, capsys):
    for name in ("vshape-table1", "peano-fig10"):
        rc, out, _ = run(["params", "--preset", name], capsys)
        assert rc == 0
        f = tmp_path / "p.toml"
        f.write_text(out)
        assert load(f).layout in ("v-shaped", "peano-hasel")


def test_simulate_writes_recording_csv_plot_and_json(tmp_path, capsys):
    out_csv, out_png = tmp_path / "run.csv", tmp_path / "run.png"
    rc, out, err = run(["simulate", "--preset", "vshape-table1", "--set", "N=41", "--voltage", "6000",
                        "--force", "5", "--reset", "0.5", "--duration", "1", "--out", str(out_csv),
                        "--plot", str(out_png), "--json"], capsys)
    assert rc == 0, err
    summary = json.loads(out)
    assert {"static_stroke", "final_stroke", "unzipping_speed", "wall_time"} <= set(summary)
    assert 5e-4 < summary["static_stroke"] < 1.2e-3
    lines = [ln for ln in out_csv.read_text().splitlines() if not ln.startswith("#")]
    rows = list(csv.reader(lines))
    assert rows[0][:5] == ["time", "voltage", "force", "stroke", "current"]
    assert float(rows[1][0]) == 0.0 and abs(float(rows[-1][0]) - 1.5) < 1e-9
    assert len(rows) == 1 + 1501                     # 1 ms sampling
    assert out_png.stat().st_size > 10_000


def test_a_pulse_train_held_is_summed_up_by_its_drift_rate_not_a_dc_chord(tmp_path, capsys):
    """Under unipolar pulses the DC hold's unzipping chord (Sec. 3.1) joined the first
    pulse's peak to the stroke at rest in the last pause (1.47 mm -> 0 over 5 s, '297
    um/s'): the summary line, the plot's title and its stroke panel give the per-period
    mean stroke's drift rate instead; a DC hold keeps its unzipping speed."""
    from dfa_model import preset, simulate
    from dfa_model.io.plotting import default_title, periodic_hold
    from dfa_model.waveforms import Protocol, Unipolar
    rc, _, err = run(["simulate", "--preset", "vshape-table1", "--set", "N=41", "--voltage", "6000", "--force", "3",
                      "--waveform", "unipolar", "--frequency", "5", "--duration", "2", "--plot",
                      str(tmp_path / "u.png")], capsys)
    assert rc == 0 and "drift rate" in err and "unzipping speed" not in err
    rc, _, err = run(["simulate", "--preset", "vshape-table1", "--set", "N=41", "--voltage", "6000", "--force", "3",
                      "--reset", "0.5", "--duration", "2", "--plot", str(tmp_path / "d.png")], capsys)
    assert rc == 0 and "unzipping speed" in err and "drift rate" not in err
    p = preset("vshape-table1").replace(N=41)
    res = simulate(p, Protocol.single(Unipolar(6000, 5.0, 0.5), 2.0), load=3.0)
    rows, rate = periodic_hold(res)
    assert len(rows) == 10 and abs(rows[1, 0] - 0.2) < 1e-12
    # each period's mean sits between its rest (0) and its pulse's peak: about half the peak
    assert all(0.3 < m / hi < 0.7 for m, hi in rows[:, [1, 3]]) and abs(rate) < 0.05 * res.peak_stroke
    assert "drift rate" in default_title(res) and "unzipping speed" not in default_title(res)
    assert periodic_hold(simulate(p, Protocol.dc(6000, 1.0), load=3.0)) is None


@pytest.mark.parametrize("args,needle", [
    (["--set", "a=0.06"], "a: semi-aperture"),
    (["--set", "foo=1"], "foo: unknown key"),
    (["--set", "N=1"], "N: got 1"),
    (["--waveform", "bipolar"], "--frequency: required"),
    (["--frequency", "-3", "--waveform", "bipolar"], "frequency: got -3"),
])
def test_bad_input_is_one_line(capsys, args, needle):
    rc, out, err = run(["simulate", "--preset", "vshape-table1", "--voltage", "6000", "--duration", "0.1"] + args, capsys)
    assert rc == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("dfa: error:") and needle in lines[0]


def test_missing_params_file(capsys, tmp_path):
    rc, _, err = run(["simulate", "--params", str(tmp_path / "none.toml"), "--voltage", "1", "--duration", "1"], capsys)
    assert rc == 2 and "cannot read" in err


def test_console_script_runs():
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--voltage",
                        "100", "--force", "5", "--duration", "0.2", "--json"], capture_output=True, text=True)
    assert r.returncode == 0
    assert json.loads(r.stdout)["final_stroke"] == 0.0
    assert "did not zip" in r.stderr                   # a warning, not a failure


def test_full_unzipping_warns_and_returns_a_result(vshape81):
    import warnings as w

    from dfa_model import PhysicsWarning, Protocol, simulate
    with w.catch_warnings(record=True) as caught:
        w.simplefilter("always", PhysicsWarning)
        r = simulate(vshape81, Protocol.dc(6000, 20.0), load=9.0)        # 9 N: unzips within 20 s
    assert any("fully unzipped" in str(c.message) for c in caught)
    assert r.final_stroke == 0.0 and r.x.max() > 2e-4


def test_every_step_output(tmp_path, capsys):
    out = tmp_path / "s.csv"
    rc = main(["simulate", "--preset", "vshape-table1", "--voltage", "6000", "--force", "5", "--duration", "2",
               "--dt", "0", "--out", str(out)])
    assert rc == 0
    rows = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")][1:]     # after the header
    t = [float(ln.split(",")[0]) for ln in rows]
    assert 10 < len(t) < 500 and t[-1] == 2.0 and all(b > a for a, b in zip(t, t[1:]))


# ---------------------------------------------------------------- issue 8, one case per defect
SIM = ["simulate", "--preset", "vshape-table1", "--voltage", "6000", "--duration", "0.1"]


@pytest.mark.parametrize("extra,needle", [
    (["--out", "/nonexistent-folder/x.csv"], "--out: folder '/nonexistent-folder' does not exist"),
    (["--out", "."], "--out: expected a file name, got '.'"),
    (["--out", ".."], "--out: '..' is a folder"),
    (["--plot", "run.svgz"], "--plot: 'run.svgz' has the suffix '.svgz'; expected one of .png"),
    (["--out", "/proc/dfa.csv"], "--out: cannot create a file in folder '/proc'"),
    (["--set", "N=inf"], "N: got inf, expected an integer"),
    (["--set", "N=nan"], "N: got nan"),
    (["--duration", "1e7"], "--dt: 1e+10 output samples"),
    (["--frequency", "5"], "--frequency: does not apply to --waveform dc"),
    (["--reset-frequency", "5"], "--reset-frequency: applies only with --reset"),
    (["--set", "rho_l=2e12", "--set", "rho_l=3e12"], "--set: rho_l given twice"),
    (["--set", "m_rho=1"], "resistivity.m_rho: does not apply to law 'constant'"),
    (["--voltage", "1e9"], "argument --voltage: got 1e9, expected a finite number >= -1e+06 and <= 1e+06"),
    (["--json=1"], "argument --json: takes no value"),
])
def test_issue8_bad_input_is_one_line(tmp_path, monkeypatch, capsys, extra, needle):
    monkeypatch.chdir(tmp_path)
    rc, _, err = run(SIM + extra, capsys)
    lines = err.strip().splitlines()
    assert rc == 2 and len(lines) == 1 and lines[0].startswith("dfa: error: ") and needle in lines[0], err


def test_peano_volume_and_nominal_integer(tmp_path, capsys):
    rc, _, err = run(["simulate", "--preset", "peano-fig10", "--voltage", "6000", "--duration", "0.1",
                      "--set", "volume=1e-15"], capsys)
    assert rc == 2 and "volume: 1e-15 m^3 leaves the pouch nearly flat" in err
    f = tmp_path / "p.toml"
    f.write_text(load_text("vshape-table1").replace("N = 81", "N = 81.0"))
    rc, out, err = run(["simulate", "--params", str(f), "--voltage", "6000", "--duration", "0.05", "--json"], capsys)
    assert rc == 0, err                                  # 81.0 is read as 81


def load_text(name):
    from dfa_model.io.parameters import preset_text
    return preset_text(name)


def test_negative_numbers_are_values(capsys):
    a = run(SIM + ["--force", "-1e2", "--json"], capsys)
    b = run(SIM + ["--force=-1e2", "--json"], capsys)
    assert a[0] == b[0] == 0 and json.loads(a[1])["final_stroke"] == json.loads(b[1])["final_stroke"]


def test_solver_failure_keeps_the_partial_result(tmp_path, capsys):
    out = tmp_path / "run.csv"
    rc, _, err = run(SIM + ["--max-steps", "15", "--out", str(out)], capsys)
    assert rc == 2 and "step limit" in err and "the partial result (up to t = " in err and str(out) in err
    text = out.read_text()
    assert "# PARTIAL:" in text and len(text.splitlines()) > 4


def test_sweep_results_survive_a_failing_out(tmp_path, monkeypatch, capsys):
    """The --out check passes, then the write fails after the runs (disk full, folder
    removed): the rows go to a temporary file named in the error."""
    from dfa_model import sweep
    real = sweep.write_csv
    target = tmp_path / "s.csv"

    def flaky(rows, path):
        if str(path) == str(target):
            raise OSError(28, "No space left on device")
        real(rows, path)

    monkeypatch.setattr(sweep, "write_csv", flaky)
    rc, _, err = run(["sweep", "--preset", "vshape-table1", "--set", "N=21", "--voltage", "6000", "--duration",
                      "0.05", "--vary", "rho_l=2e12,3e12", "--workers", "1", "--quiet", "--out", str(target)], capsys)
    assert rc == 2 and "No space left on device" in err and "the results are in " in err
    kept = err.strip().split("the results are in ")[-1]
    rows = list(csv.DictReader(open(kept)))
    assert [r["status"] for r in rows] == ["ok", "ok"]


def test_unreachable_scheduler_is_one_line_within_its_timeout(capsys):
    pytest.importorskip("dask.distributed")
    import time
    t0 = time.perf_counter()
    rc, _, err = run(["sweep", "--preset", "vshape-table1", "--voltage", "6000", "--duration", "0.05",
                      "--vary", "rho_l=2e12", "--scheduler", "tcp://127.0.0.1:9", "--quiet"], capsys)
    assert rc == 2 and err.startswith("dfa: error: --scheduler: cannot reach") and len(err.strip().splitlines()) == 1
    assert time.perf_counter() - t0 < 30


def test_sweep_setup_errors_before_any_run(capsys):
    for vary, needle in ((["rho_l=2e12", "rho_l=3e12"], "--vary: rho_l given twice"),
                         (["theta0=20,30"], "theta0: applies only to layout 'v-shaped'"),
                         (["a=0.01"], "geometry.a: does not apply to layout 'peano-hasel'")):
        argv = ["sweep", "--preset", "peano-fig10" if "theta0" in vary[0] or "a=" in vary[0] else "vshape-table1",
                "--voltage", "6000", "--duration", "0.05", "--quiet"]
        for v in vary:
            argv += ["--vary", v]
        rc, _, err = run(argv, capsys)
        assert rc == 2 and needle in err, err


def test_internal_errors_are_one_line(monkeypatch, capsys):
    """The safety net: a bug is one line and exit 70, never a traceback (the fuzz suite
    asserts it is never reached)."""
    import dfa_model.cli as cli
    monkeypatch.setattr(cli, "cmd_params", lambda args: 1 / 0)
    rc, _, err = run(["params"], capsys)
    assert rc == 70 and err.startswith("dfa: internal error: ZeroDivisionError") and "Traceback" not in err
