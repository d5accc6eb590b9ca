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
    t = [float(ln.split(",")[0]) for ln in out.read_text().splitlines()[3:]]
    assert 10 < len(t) < 500 and t[-1] == 2.0 and all(b > a for a, b in zip(t, t[1:]))
