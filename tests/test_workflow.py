"""The journey of README 'From recordings to a drive', run small (N = 21) as a user runs
it, every joint asserted: recordings of a device with hidden physics -> dfa diagnose ->
improved.toml -> dfa reduce -> dfa design --out drive.toml -> dfa simulate --protocol
(the replay) -> dfa hold -> the SSP system with the improved actuator and the designed
drive in fmpy (examples/workflow.py --quick writes joints.json)."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from dfa_model.io import parameters

HERE = Path(__file__).resolve().parent.parent / "examples"

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
if shutil.which("cc") is None and shutil.which("gcc") is None:
    pytest.skip("the FMUs need a C compiler", allow_module_level=True)


@pytest.fixture(scope="module")
def journey(tmp_path_factory):
    out = tmp_path_factory.mktemp("workflow")
    env = dict(os.environ, DFA_EXAMPLES_OUT=str(out), DFA_EXAMPLES_QUICK="1")
    r = subprocess.run([sys.executable, str(HERE / "workflow.py"), "--quick"], cwd=HERE, env=env, capture_output=True,
                       text=True, timeout=1500)
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    root = out / "workflow"
    return root, json.loads((root / "joints.json").read_text()), r.stdout


def test_diagnosis_names_the_hidden_physics_and_writes_the_improved_model(journey):
    root, j, _ = journey
    d = j["diagnosis"]
    assert d["named"] == ["stiffness"]
    assert d["k"] == pytest.approx(j["k_true"], rel=0.05)
    assert d["heldout_improved"] < 0.5 * d["heldout_baseline"]
    p = parameters.load(root / d["improved_params"])
    assert p.k == pytest.approx(d["k"], rel=1e-12)


def test_the_designed_drive_replays_within_2_percent(journey):
    _, j, _ = journey
    v, rep = j["design"]["verified"], j["replay"]
    assert v["meets"] and j["design"]["duty"] == 1.0
    assert rep["ripple"] == pytest.approx(v["ripple"], rel=0.02)
    assert rep["drift"] == pytest.approx(v["drift"], rel=0.02, abs=1e-9)
    assert rep["input_power"] == pytest.approx(j["design"]["power"]["input"], rel=0.02)


def test_the_hold_on_the_improved_surrogate_holds(journey):
    _, j, _ = journey
    closed, dc = j["hold"]["closed_loop"], j["hold"]["open_loop_dc"]
    assert abs(closed["drift"]) < 5e-6 < dc["drift"]


def test_the_system_holds_the_stroke_within_the_spec_in_cosimulation(journey):
    root, j, out = journey
    c, spec = j["cosimulation"], j["spec"]
    assert c["meets"], c
    assert c["ripple"] <= spec["max_ripple"] and abs(c["drift"]) <= spec["max_drift"]
    # the load FMU carries the design's load (its mass: F / g at rest)
    assert c["load_mean"] == pytest.approx(5.0, rel=0.02)
    assert (root.parent / "workflow.png").is_file() and (root / "design.png").is_file()
    for name in ("report/improved.toml", "act.json", "drive.toml", "system.ssp", "replay.csv"):
        assert (root / name).is_file(), name
