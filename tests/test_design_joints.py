"""The joints around `dfa design` and `dfa hold`: a designed drive written as a protocol
file replays in `dfa simulate` with the design's verified ripple and drift; the commands
take a fitted surrogate (--model), refuse one of another device, and fit and cache one
per parameter set without it."""
from __future__ import annotations

import json
import subprocess
import sys

import pytest

import reduced

SMALL = ["--preset", "vshape-table1", "--set", "N=21"]
SPEC = ["--voltage", "6000", "--force", "5", "--max-ripple", "120e-6", "--max-drift", "15e-6", "--horizon", "10",
        "--slew-rate", "4e7"]


def dfa(*args, check=True):
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", *map(str, args)], capture_output=True, text=True)
    if check:
        assert r.returncode == 0, r.stderr
    return r


def last_json(r):
    """--json: stdout is the JSON document alone (the summary goes to stderr), so it pipes
    into jq or json.load."""
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def designed(tmp_path_factory):
    d = tmp_path_factory.mktemp("design")
    r = dfa("design", *SMALL, *SPEC, "--out", d / "drive.toml", "--plot", d / "design.png", "--json", "--quiet")
    return d, r, last_json(r)


def test_designed_drive_replays_with_the_verified_ripple_and_drift(designed):
    d, r, out = designed
    assert out["feasible"] and out["verified"]["meets"] and out["protocol"] == str(d / "drive.toml")
    assert out["duty"] == 1.0 and out["positive_share"] == 0.5 and out["slew_rate"] == pytest.approx(4e7)
    rep = last_json(dfa("simulate", *SMALL, "--protocol", d / "drive.toml", "--json"))
    v = out["verified"]
    assert rep["ripple"] == pytest.approx(v["ripple"], rel=0.02)
    assert rep["drift"] == pytest.approx(v["drift"], rel=0.02, abs=1e-9)
    assert rep["input_power"] == pytest.approx(v["input_power"], rel=0.02)
    assert rep["period"] == pytest.approx(1 / out["frequency"], rel=1e-12)
    text = (d / "drive.toml").read_text()
    assert "full model over the horizon: ripple" in text and "# the charge-balanced start" in text


def test_design_names_its_power(designed):
    _, r, out = designed
    pw = out["power"]
    assert set(pw) == {"hard_switched_dissipation", "input"}
    assert pw["input"] == out["verified"]["input_power"] and 0 < pw["input"] < pw["hard_switched_dissipation"]
    # the summary goes to stderr under --json (stdout is the JSON alone)
    assert "dissipated by a hard-switched source" in r.stderr and "delivered to the actuator" in r.stderr


def test_design_plot_is_written(designed):
    d, _, _ = designed
    from matplotlib.image import imread
    img = imread(d / "design.png")
    assert img.shape[0] > 500 and img.shape[1] > 700


def test_design_fits_once_and_then_reads_the_cache(designed):
    _, r, _ = designed
    again = dfa("design", *SMALL, *SPEC, "--quiet")
    assert "surrogate from the cache" in again.stdout, again.stdout
    assert "fitted now" in r.stdout or "from the cache" in r.stdout


@pytest.fixture(scope="module")
def model_file(tmp_path_factory):
    from dfa_model import preset
    path = tmp_path_factory.mktemp("model") / "act.json"
    reduced.build(preset("vshape-table1").replace(N=21), "charge").save(path)
    return path


def test_design_and_hold_take_a_model_file(model_file, tmp_path):
    out = last_json(dfa("design", "--model", model_file, *SPEC, "--json"))
    assert out["surrogate"].startswith("parameters and surrogate from") and out["feasible"]
    h = last_json(dfa("hold", "--model", model_file, "--stroke", "0.8e-3", "--force", "5", "--duration", "3", "--json"))
    m = h["metrics"]["closed loop"]
    assert {"drift", "hard_switched_power", "rms_dev"} <= set(m) and abs(m["drift"]) < 20e-6


def test_a_model_of_another_device_is_refused(model_file, tmp_path):
    for cmd in (["design", *SPEC], ["hold", "--stroke", "0.8e-3", "--force", "5", "--duration", "3"]):
        r = dfa(cmd[0], "--model", model_file, *SMALL, "--set", "rho_l=3e12", *cmd[1:], check=False)
        assert r.returncode == 2, r.stderr
        line = r.stderr.strip()
        assert "\n" not in line and "another device" in line and "rho_l = 2000000000000.0" in line, line
    # another discretization is the same device: a note, not an error
    r = dfa("design", "--model", model_file, "--preset", "vshape-table1", "--set", "N=41", *SPEC, "--json")
    assert "the surrogate was fitted at N = 21; the full-model checks run at N = 41" in r.stdout


def test_compare_takes_the_designed_drive(designed, model_file):
    d, _, _ = designed
    out = last_json(dfa("compare", model_file, "--protocol", d / "drive.toml", "--json"))
    assert out["ripple_full"] > 0 and out["ripple_reduced"] > 0 and out["drift_full"] is not None
    assert out["relative_rms_error"] < 0.05
    r = dfa("compare", model_file, "--protocol", d / "drive.toml", "--voltage", "6000", check=False)
    assert r.returncode == 2 and "remove --voltage" in r.stderr
