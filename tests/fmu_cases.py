"""Run through tests/test_fmu.py, in a separate process. The FMU: build, validation, fmpy simulation against the direct model, life cycle,
state rollback, error paths, a C host, and loading a copy in a fresh process; a hostile C
host with faults injected at every entry point (tests/fmu_host_faults.c,
tests/fmu_faulty.py); a fuzz of FMI call sequences against the state table."""
import dataclasses
import os
import shutil
import subprocess
import sys
import warnings
import zipfile
from pathlib import Path

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
from fmpy.fmi1 import FMICallException  # noqa: E402

from dfa_model import PhysicsWarning, Protocol, preset, simulate  # noqa: E402
from dfa_model.numerics.stepper import Stepper  # noqa: E402
from dfa_model.waveforms import Sampled  # noqa: E402
from fmu import build_fmu  # noqa: E402
# the FMU tests' shared helpers and fixtures md, unzipped (of fmu_path below)
from fmu_support import H, description, direct_stroke, md, slave, unzipped, vr  # noqa: E402,F401


@pytest.fixture(scope="module")
def fmu_path(tmp_path_factory):
    return build_fmu(preset("vshape-table1"), tmp_path_factory.mktemp("fmu") / "DFAActuator.fmu")


def fmu_stroke(md, unzipped, V, reals=None, booleans=None, stop_time=None):
    """Stroke at every step of H through the FMU, voltage V[k] on step k, 5 N load."""
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0, stopTime=stop_time)
    s.enterInitializationMode()
    for key, value in (reals or {}).items():
        s.setReal([r[key]], [value])
    for key, value in (booleans or {}).items():
        s.setBoolean([r[key]], [value])
    s.exitInitializationMode()
    x = []
    for k in range(len(V)):
        s.setReal([r["voltage"], r["force"]], [V[k], 5.0])
        s.doStep(k * H, H)
        x.append(s.getReal([r["stroke"]])[0])
    s.terminate()
    s.freeInstance()
    return np.array(x)


def bipolar(n, v=6000.0, period_steps=34):
    return np.where((np.arange(n) // (period_steps // 2)) % 2 == 0, v, -v)


# SI base-unit exponents of the units the FMUs use, by hand (tests/test_fmu_units.py)
from test_fmu_units import SI  # noqa: E402


def check_description(fmu_path, ranges: dict):
    """The model description's units, display units, ranges and nominal values: every
    Real has a unit defined in UnitDefinitions with the SI exponents of SI (written out
    by hand there); a display unit is one of its unit's, its factor that of the prefix;
    `ranges` (name -> (min, max), None for no bound) are the min/max written; every start
    lies within [min, max]; nominal values are > 0; the initial outputs depend on the
    parameters only. Returns the variables' typed elements by name."""
    import math
    root = description(fmu_path)
    units = {u.get("name"): u for u in root.find("UnitDefinitions")}
    prefix = {"m": 1e-3, "u": 1e-6, "n": 1e-9, "k": 1e3, "M": 1e6}
    typed, by_index = {}, {}
    for i, sv in enumerate(root.find("ModelVariables"), start=1):
        name, t = sv.get("name"), sv[0]
        typed[name], by_index[i] = t, sv
        if t.tag == "Real":
            u = units[t.get("unit")]                 # KeyError: a unit not defined
            assert {k: int(v) for k, v in u.find("BaseUnit").attrib.items()} == SI[u.get("name")], name
            if t.get("displayUnit"):
                d = {x.get("name"): float(x.get("factor", "1")) for x in u.findall("DisplayUnit")}[t.get("displayUnit")]
                name_d = t.get("displayUnit")
                if name_d == "deg":
                    assert math.isclose(d, 180 / math.pi, rel_tol=1e-14)
                elif name_d[1:] == u.get("name"):    # a prefixed unit: factor 1 / prefix
                    assert math.isclose(d, 1 / prefix[name_d[0]], rel_tol=1e-15), name
            if t.get("nominal") is not None:
                assert float(t.get("nominal")) > 0, name
        if name in ranges:
            lo, hi = ranges[name]
            assert (t.get("min") is None) == (lo is None) and (t.get("max") is None) == (hi is None), name
            assert lo is None or float(t.get("min")) == lo
            assert hi is None or float(t.get("max")) == hi
        else:
            assert t.get("min") is None and t.get("max") is None, name
        if t.get("start") is not None and t.tag in ("Real", "Integer"):
            assert float(t.get("min", "-inf")) <= float(t.get("start")) <= float(t.get("max", "inf")), name
    for u in root.find("ModelStructure/InitialUnknowns"):
        deps = [by_index[int(k)] for k in u.get("dependencies").split()]
        assert all(sv.get("causality") == "parameter" for sv in deps)
    return typed


def test_validates_and_documents(fmu_path, md):
    assert fmpy.validation.validate_fmu(str(fmu_path)) == []
    from fmu.dfa_actuator import PARAM_RANGES, RANGES
    typed = check_description(fmu_path, {**RANGES, **PARAM_RANGES})
    assert typed["stroke"].get("displayUnit") == "mm" and typed["voltage"].get("displayUnit") == "kV"
    assert typed["rho_l"].get("unit") == "Ohm.m" and typed["b"].get("unit") == "N.s/m"
    assert typed["eps_r_f"].get("unit") == "1"
    assert typed["l"].get("min") == "0" and typed["l"].get("max") == "10"            # SPEC: 0 < l <= 10
    assert typed["N"].get("min") == "3" and typed["N"].get("max") == "100000"
    assert float(typed["stroke"].get("nominal")) == pytest.approx(4.565e-3, rel=1e-3)    # x_e of Table 1
    assert float(typed["voltage"].get("nominal")) == 6000.0
    names = {v.name: v for v in md.modelVariables}
    for out in ("stroke", "velocity", "zipped_length", "zipping_angle", "electrostatic_force", "current",
                "capacitance", "stored_energy"):
        assert names[out].causality == "output" and names[out].description
    assert names["voltage"].causality == "input" and names["voltage"].unit == "V"
    assert names["rho_l"].causality == "parameter" and names["rho_l"].variability == "fixed"
    assert float(names["rho_l"].start) == preset("vshape-table1").rho_l and names["rho_l"].unit == "Ohm.m"
    assert names["N"].type == "Integer" and names["scheme"].type == "String"
    assert float(md.defaultExperiment.stopTime) == 23.0
    with zipfile.ZipFile(fmu_path) as z:
        assert "resources/dfa_params.toml" in z.namelist()


def test_matches_direct_model(md, unzipped):
    """land_on_communication_points = true, same sampled input (bipolar 30 Hz, then DC):
    stroke within 1e-6 of `simulate`."""
    warnings.simplefilter("ignore", PhysicsWarning)
    n = 600
    V = np.concatenate([bipolar(300), np.full(n - 300, 6000.0)])
    x = fmu_stroke(md, unzipped, V, reals={"v_nominal": 6000.0}, booleans={"land_on_communication_points": True})
    t = np.arange(n + 1) * H
    ref = simulate(preset("vshape-table1"), Protocol.single(Sampled(t[:-1], V, hold=True), n * H), 5.0,
                   t_eval=t[1:])
    assert np.max(ref.x) > 5e-4
    assert np.max(np.abs(np.array(x) - ref.x)) <= 1e-6 * np.max(np.abs(ref.x))


def test_state_rollback_is_bitwise(md, unzipped):
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    outs = [r[k] for k in ("stroke", "current", "electrostatic_force", "stored_energy")]
    for k in range(40):
        s.setReal([r["voltage"], r["force"]], [6000.0 if k < 20 else -6000.0, 5.0])
        s.doStep(k * H, H)
    state = s.getFMUstate()
    runs = []
    for _ in range(2):
        s.setFMUstate(state)
        vals = []
        for k in range(40, 60):
            s.setReal([r["voltage"], r["force"]], [6000.0 if k < 50 else -6000.0, 4.0])
            s.doStep(k * H, H)
            vals.append(s.getReal(outs))
        runs.append(np.array(vals))
    assert np.array_equal(runs[0], runs[1])
    assert runs[0][-1][0] > 0
    s.freeFMUstate(state)
    s.terminate()
    s.freeInstance()


def test_life_cycle_reset_and_two_instances(md, unzipped):
    r = vr(md)
    a, b = slave(md, unzipped, "a"), slave(md, unzipped, "b")
    for s in (a, b):
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
    b.setReal([r["rho_l"]], [1e12])          # instances are independent
    for s in (a, b):
        s.exitInitializationMode()
    xa, xb = [], []
    for k in range(300):
        for s, xs in ((a, xa), (b, xb)):
            s.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
            s.doStep(k * H, H)
        xa.append(a.getReal([r["stroke"]])[0])
        xb.append(b.getReal([r["stroke"]])[0])
    assert xa[-1] > 0 and xb[-1] > 0 and xa[-1] != xb[-1]
    # reset: back to the start values, and the same trajectory again
    a.reset()
    a.setupExperiment(startTime=0.0)
    a.enterInitializationMode()
    a.exitInitializationMode()
    assert a.getReal([r["stroke"]])[0] == 0.0
    for k in range(300):
        a.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
        a.doStep(k * H, H)
    assert a.getReal([r["stroke"]])[0] == xa[-1]
    for s in (a, b):
        s.terminate()
        s.freeInstance()


def test_errors_are_fmi2error_and_the_instance_survives(md, unzipped, capsys):
    """Bad parameter values, bad strings and NaN inputs return fmi2Error (status 3) with
    a log line naming the variable and its valid range; the instance keeps working."""
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    for setter, vref, value, words in (("setReal", r["rho_l"], -1.0, ("rho_l", "-1")),
                                       ("setInteger", r["N"], 1, ("N", "<= value <=")),
                                       ("setString", r["scheme"], "bogus", ("scheme", "continuum"))):
        with pytest.raises(FMICallException) as exc:
            getattr(s, setter)([vref], [value])
        assert exc.value.status == 3
        log = capsys.readouterr().out
        assert "[ERROR]" in log and all(w in log for w in words), log
    s.setReal([r["rho_l"]], [preset("vshape-table1").rho_l])   # still usable: a valid value is taken
    s.exitInitializationMode()
    s.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
    s.doStep(0.0, H)
    with pytest.raises(FMICallException) as exc:
        s.setReal([r["voltage"]], [float("nan")])
    assert exc.value.status == 3 and "finite" in capsys.readouterr().out
    s.doStep(H, H)                                   # the NaN was refused, the run goes on
    assert abs(s.getReal([r["stroke"]])[0] - direct_stroke(2)) <= 1e-12
    with pytest.raises(FMICallException) as exc:     # a time that does not continue the run
        s.doStep(5.0, H)
    assert exc.value.status == 3 and "currentCommunicationPoint" in capsys.readouterr().out
    s.terminate()
    s.freeInstance()


def test_inconsistent_parameters_fail_initialization(md, unzipped, capsys):
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([r["a"]], [0.06])                        # a > l: caught when the set is complete
    with pytest.raises(FMICallException) as exc:
        s.exitInitializationMode()
    assert exc.value.status == 3 and "initialization failed" in capsys.readouterr().out
    s.setReal([r["a"]], [preset("vshape-table1").a])   # fixed: initialization goes through
    s.exitInitializationMode()
    s.freeInstance()


def test_default_steps_as_simulate_does(md, unzipped):
    """Default stepping (land_on_communication_points = false): with the inputs switching
    at communication points, the solver's states after each switch are those of `simulate`
    with the same switches (the same final stroke). Between switches the stroke is read off
    the solver step in progress; a step that a later switch cuts short is redone, so points
    before a switch differ from simulate's within the local error bound rtol (x_e + x).
    Most points are answered by the binary in C (fast_step); the Stepper stepping freely
    in Python gives the same numbers bit for bit."""
    warnings.simplefilter("ignore", PhysicsWarning)
    n = 600
    V = np.concatenate([bipolar(300), np.full(n - 300, 6000.0)])
    x = fmu_stroke(md, unzipped, V, reals={"v_nominal": 6000.0}, stop_time=n * H)
    st = Stepper(preset("vshape-table1"), v_nominal=6000.0, t_end=n * H, exact=False)
    direct = []
    for k in range(n):
        st.t = k * H                      # the master's clock, as the slave takes it
        st.step(H, V[k], 5.0)
        direct.append(st.out[0])
    assert np.array_equal(x, direct), np.max(np.abs(x - direct))
    switches = np.flatnonzero(np.diff(V)) + 1
    t_sw = np.concatenate([[0.0], switches * H])
    proto = Protocol.single(Sampled(t_sw, V[np.concatenate([[0], switches])], hold=True), n * H)
    t = np.arange(1, n + 1) * H
    ref = simulate(preset("vshape-table1"), proto, 5.0, t_eval=t)
    assert np.max(ref.x) > 5e-4
    assert abs(x[-1] - ref.x[-1]) <= 1e-12 * ref.x[-1]
    p, x_e = preset("vshape-table1"), st.model.kin.x_e
    assert np.max(np.abs(x - ref.x)) <= p.rtol * (x_e + np.max(ref.x))


def test_free_stepping_is_accurate(md, unzipped):
    """land_on_communication_points = false: the solver steps across communication
    points. Its outputs stay as close to a tight-tolerance reference as simulate's."""
    warnings.simplefilter("ignore", PhysicsWarning)
    n = 400
    V = bipolar(n)
    x = fmu_stroke(md, unzipped, V, stop_time=n * H)
    t = np.arange(n + 1) * H
    proto = Protocol.single(Sampled(t[:-1], V, hold=True), n * H)
    ref = simulate(preset("vshape-table1"), proto, 5.0, t_eval=t[1:]).x
    tight = simulate(preset("vshape-table1"), proto, 5.0, t_eval=t[1:], rtol=1e-8).x
    err_free = np.max(np.abs(np.array(x) - tight))
    err_sim = np.max(np.abs(ref - tight))
    assert err_free <= 2e-3 * np.max(tight), (err_free, err_sim)
    assert err_free <= 10 * err_sim, (err_free, err_sim)


def test_serialized_state_restores(md, unzipped):
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    for k in range(30):
        s.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
        s.doStep(k * H, H)
    data = s.serializeFMUstate(s.getFMUstate())
    for k in range(30, 50):
        s.doStep(k * H, H)
    x_end = s.getReal([r["stroke"]])[0]
    s.setFMUstate(s.deSerializeFMUstate(data))
    assert s.getReal([r["stroke"]])[0] != x_end
    for k in range(30, 50):
        s.doStep(k * H, H)
    assert s.getReal([r["stroke"]])[0] == x_end
    s.freeInstance()


def test_copy_loads_in_fresh_process(fmu_path, tmp_path):
    copy = tmp_path / "elsewhere" / "actuator.fmu"
    copy.parent.mkdir()
    shutil.copy(fmu_path, copy)
    code = ("import fmpy, numpy as np\n"
            f"r = fmpy.simulate_fmu({str(copy)!r}, stop_time=0.2, step_size=1e-3, output=['stroke'],\n"
            "    start_values={'voltage': 6000.0, 'force': 5.0})\n"
            "print(r['stroke'][-1])\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    x = float(out.stdout.split()[-1])
    assert abs(x - direct_stroke(200, t_end=0.2)) <= 1e-9 * abs(x)


def _run_c_host(md, unzipped, tmp_path, nsteps=100):
    exe = tmp_path / "fmu_host"
    src = Path(__file__).with_name("fmu_host.c")
    cc = subprocess.run(["gcc", "-O1", "-o", str(exe), str(src), "-ldl"], capture_output=True, text=True)
    assert cc.returncode == 0, cc.stderr
    so = Path(unzipped) / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    r = vr(md)
    uri = (Path(unzipped) / "resources").as_uri()
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "LD_LIBRARY_PATH", "PYTHONPATH",
                                                            "PYTHONHOME")}
    return subprocess.run([str(exe), str(so), uri, md.guid, str(r["voltage"]), str(r["force"]), str(r["stroke"]),
                           str(nsteps), str(H)], capture_output=True, text=True, timeout=600, env=env)


needs_gcc = pytest.mark.skipif(not sys.platform.startswith("linux") or shutil.which("gcc") is None,
                               reason="needs Linux and gcc")


@needs_gcc
def test_c_host_dlopen_rtld_now(md, unzipped, tmp_path):
    """A C program dlopens the binary with RTLD_NOW (no libpython preloaded) and runs
    instantiate, setup, initialize, 100 doSteps, getReal, terminate, free."""
    out = _run_c_host(md, unzipped, tmp_path)
    lines = out.stdout.split("\n")
    assert lines[0].startswith("stroke") and lines[1] == "freed", out.stdout + out.stderr[-2000:]
    x = float(lines[0].split()[1])
    assert x > 0 and abs(x - direct_stroke(100)) <= 1e-9 * x


@needs_gcc
def test_c_host_exits_cleanly(md, unzipped, tmp_path):
    assert _run_c_host(md, unzipped, tmp_path, nsteps=5).returncode == 0


def test_cosimulation_with_drive_and_load(fmu_path, tmp_path):
    """fmpy runs the actuator with the drive-electronics and mass-spring load FMUs,
    exchanging signals every 1 ms: the drive's slew-rate and current limits hold, a
    30 Hz inversion holds the stroke, and the DC hold after a charge reset relaxes."""
    from fmu import build_companion_fmu
    from fmu.cosim import cosimulate
    drive = build_companion_fmu("drive", tmp_path / "drive.fmu")
    load = build_companion_fmu("load", tmp_path / "load.fmu")
    from fmu import drive_electronics, mass_spring_load
    for f, module in ((drive, drive_electronics), (load, mass_spring_load)):
        assert fmpy.validation.validate_fmu(str(f)) == []
        check_description(f, module.RANGES)
    runs = {mode: cosimulate(fmu_path, drive, load, 4.0, drive_start={"mode": mode, "reset_time": 1.0})
            for mode in ("reset_dc", "inversion")}
    for r in runs.values():
        assert np.max(np.abs(np.diff(r["voltage"]))) <= 5e6 * H * (1 + 1e-9)        # slew rate
        assert np.max(np.abs(r["supply_current"])) <= 2e-3 * (1 + 1e-9)             # current limit
        assert np.max(np.abs(r["supply_current"])) >= 0.99 * 2e-3                    # ... and it bites
        assert abs(np.mean(r["force"][1000:]) - 0.51 * 9.81) < 0.1 * 0.51 * 9.81    # the load hangs on it
    inv, dc = runs["inversion"]["stroke"], runs["reset_dc"]["stroke"]
    assert abs(np.mean(inv[3500:]) - np.mean(inv[500:1000])) <= 0.01 * np.mean(inv[500:1000])
    early, late = np.mean(dc[1500:2000]), np.mean(dc[3500:])
    assert late < 0.98 * early and late > 0.5 * early


def test_ssp_system_runs_in_fmpys_master(tmp_path):
    """`dfa fmu build --system` writes an SSP (the SSD validates against the SSP 1.0
    schema in fmpy's reader); fmpy's SSP master runs it and gives the stroke of
    fmu.cosim.cosimulate with the same FMUs. Its row k holds the values after the step
    from t_k (cosimulate's point k + 1); its time is summed step by step (3e-13 s off
    after 3500 steps), and its first step sees zero inputs (nothing moves at 0 V), so the
    strokes agree to rounding, growing to ~1e-9 m, not bit for bit."""
    from fmpy.ssp.simulation import simulate_ssp
    from dfa_model.cli import main
    from fmu.cosim import cosimulate
    ssp = tmp_path / "system.ssp"
    assert main(["fmu", "build", "--preset", "vshape-table1", "--system", "--out", str(ssp)]) == 0
    warnings.simplefilter("ignore", PhysicsWarning)
    T = 3.5
    r = simulate_ssp(str(ssp), stop_time=T, step_size=H)
    with zipfile.ZipFile(ssp) as z:
        z.extractall(tmp_path / "ssp")
    res = tmp_path / "ssp" / "resources"
    c = cosimulate(res / "DFAActuator.fmu", res / "DriveElectronics.fmu", res / "MassSpringLoad.fmu", T, H)
    n = len(c["t"]) - 1
    assert len(r) >= n and np.max(c["stroke"]) > 5e-4
    for ssp_name, name in (("actuator.stroke", "stroke"), ("drive.voltage", "voltage"), ("load.force", "force")):
        assert np.max(np.abs(r[ssp_name][:n] - c[name][1:])) <= 1e-6 * np.max(np.abs(c[name])), ssp_name


# ---------------------------------------------------------------------- fault injection
# Scenarios of tests/fmu_host_faults.c: one per injected fault's entry point (the test
# slave tests/fmu_faulty.py), and the generic abuse of the C binary.
FAULT_SCENARIOS = ("instantiate", "invalid_instance", "arguments", "states", "setup_experiment",
                   "enter_initialization_mode", "exit_initialization_mode", "terminate", "do_step", "do_step_solver",
                   "do_step_wrong_type", "do_step_false", "get_real", "get_integer", "get_boolean", "get_string",
                   "set_real", "set_integer", "set_boolean", "set_string", "_get_fmu_state", "_set_fmu_state",
                   "_fmu_state_to_bytes", "_fmu_state_from_bytes", "log_queue")


@pytest.fixture(scope="module")
def fault_run(tmp_path_factory):
    """Build the fault-injection FMU, make the bad-resource copies (defect 1: an unknown
    slave module, an unknown key in dfa_params.toml), compile the hostile C host and run
    it once; returns its result lines by scenario."""
    if not sys.platform.startswith("linux") or shutil.which("gcc") is None:
        pytest.skip("needs Linux and gcc")
    from fmu.build import build_actuator_variant
    tmp = tmp_path_factory.mktemp("faults")
    path = build_actuator_variant(Path(__file__).with_name("fmu_faulty.py"), "FaultyActuator", tmp / "Faulty.fmu")
    md_f = fmpy.read_model_description(str(path))
    root = Path(fmpy.extract(str(path), str(tmp / "faulty")))
    bad_module, bad_params = tmp / "bad_module", tmp / "bad_params"
    for d in (bad_module, bad_params):
        shutil.copytree(root, d)
    (bad_module / "resources" / "slavemodule.txt").write_text("no_such_module\n")
    toml = bad_params / "resources" / "dfa_params.toml"
    toml.write_text(toml.read_text().replace("[geometry]\n", "[geometry]\nbogus_key = 1.0\n", 1))
    exe = tmp / "fmu_host_faults"
    cc = subprocess.run(["gcc", "-O1", "-o", str(exe), str(Path(__file__).with_name("fmu_host_faults.c")),
                         "-I", str(Path(fmpy.__file__).parent / "c-code"), "-ldl"], capture_output=True, text=True)
    assert cc.returncode == 0, cc.stderr
    r = vr(md_f)
    so = root / "binaries" / "linux64" / f"{md_f.coSimulation.modelIdentifier}.so"
    env = {k: v for k, v in os.environ.items() if k not in ("LD_PRELOAD", "LD_LIBRARY_PATH", "PYTHONPATH",
                                                            "PYTHONHOME")}
    args = [str(exe), str(so), (root / "resources").as_uri(), str(root / "resources"),
            (bad_module / "resources").as_uri(), (bad_params / "resources").as_uri()]
    args += [str(r[k]) for k in ("voltage", "force", "stroke", "rho_l", "rho_f", "N", "scheme",
                                 "land_on_communication_points")]
    out = subprocess.run(args, capture_output=True, text=True, timeout=600, env=env)
    by = {}
    for line in out.stdout.splitlines():
        word, _, rest = line.partition(" ")
        if word in ("ok", "FAIL"):
            by.setdefault(rest.split(":")[0], []).append((word == "ok", line))
    return out, by


def test_fault_host_survives(fault_run):
    """The hostile host exits normally after every scenario, and runs no other."""
    out, by = fault_run
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    assert out.stdout.splitlines()[-1].startswith("done"), out.stdout[-3000:]
    assert set(by) == set(FAULT_SCENARIOS), set(by) ^ set(FAULT_SCENARIOS)


@pytest.mark.parametrize("scenario", FAULT_SCENARIOS)
def test_fault_scenario(fault_run, scenario):
    """Each call of the scenario returned the documented status with a log line, and the
    instance behaved as documented afterwards (see tests/fmu_host_faults.c)."""
    _, by = fault_run
    results = by.get(scenario, [])
    assert len(results) >= 2, results
    assert all(ok for ok, _ in results), "\n".join(line for ok, line in results if not ok)


# ---------------------------------------------------------------------- call-sequence fuzz
# Random sequences of FMI calls with random arguments against the actuator through
# fmpy's bound functions. For every call the status must be the one an oracle built from
# the state table (fmu/c/fmi2_python.c, FMI 2.0.x section 4.2.4) predicts, every
# fmi2Error on a live instance must come with a log line, and after every OK doStep the
# outputs are finite and the stroke >= 0.
hypothesis = pytest.importorskip("hypothesis")
import math  # noqa: E402
from ctypes import byref, c_size_t, create_string_buffer  # noqa: E402

from fmpy.fmi2 import (fmi2Boolean, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,  # noqa: E402
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2FMUstate, fmi2Integer, fmi2Real,
                       fmi2String, fmi2ValueReference)
from hypothesis import HealthCheck, given, settings, strategies as hs  # noqa: E402

from dfa_model import parameters as P  # noqa: E402
from dfa_model.physics.model import DFAModel  # noqa: E402

OK, WARNING, DISCARD, ERROR = 0, 1, 2, 3
INST, INIT, SC, SF, TERM, ERR = ("instantiated", "initializationMode", "stepComplete", "stepFailed", "terminated",
                                 "error")
ANY = {INST, INIT, SC, SF, TERM, ERR}
GET = {INIT, SC, SF, TERM, ERR}
SET = {INST, INIT, SC}
# the oracle's copy of the state table: where each call is allowed
ALLOWED = {"setup": {INST}, "enter": {INST}, "exit": {INIT}, "terminate": {SC, SF}, "reset": ANY, "get_real": GET,
           "set_real": SET, "set_int": SET, "set_bool": SET, "set_str": SET, "get_state": ANY, "set_state": ANY,
           "free_state": ANY, "serialize": ANY, "deserialize": ANY, "do_step": {SC}}
X_E = DFAModel(preset("vshape-table1")).kin.x_e
RANGES = {"voltage": (-1e6, 1e6), "force": (-1e6, 1e6)}     # dfa_model.limits, in the model description
FUZZ_STATS = {"sequences": 0, "calls": 0, "statuses": {}}
NAN, INF = float("nan"), float("inf")
KEYS = ("layout", "rho_l", "rho_t_s", "N", "scheme", "law")      # the parameter-file keys the fuzz sets


class Oracle:
    """What the FMU should answer: the state machine, the time, the experiment and the
    parameters the fuzz can change."""

    def __init__(self):
        p0 = preset("vshape-table1")
        self.state, self.time, self.start, self.stop = INST, 0.0, 0.0, None
        self.params = {**{k: getattr(p0, k) for k in KEYS}, "x0": 0.0}
        self.start_params = dict(self.params)

    def snapshot(self):
        return (self.state, self.time, self.start, self.stop, dict(self.params))

    def restore(self, snap):
        self.state, self.time, self.start, self.stop, params = snap
        self.params = dict(params)

    def exit_status(self):
        """OK, WARNING (a changed parameter that takes no part) or ERROR (no model)."""
        p = self.params
        try:
            if p["layout"] != "v-shaped":
                return ERROR                     # peano-hasel needs a volume, which stays 0 here
            # as the FMU builds them: every key given (one that takes no part is only warned
            # about), so the constructor, not replace(), which refuses such a key
            params = P.Parameters(**{**dataclasses.asdict(preset("vshape-table1")), **{k: p[k] for k in KEYS}})
            stop = self.stop if self.stop is not None and self.stop > self.start else None
            Stepper(params, v_nominal=6000.0, x0=p["x0"], t0=self.start, t_end=stop)
        except ValueError:
            return ERROR
        ignored = [k for k in KEYS[1:] if not P.applies(params, k) and p[k] != self.start_params[k]]
        return WARNING if ignored else OK

    def set_ok(self, name, kind, value, kinds):
        """Whether fmi2Set<kind> of `value` on variable `name` is accepted now."""
        if name is None or kinds[name] != kind or name == "stroke":     # unknown, wrong type, output
            return False
        if name in ("voltage", "force"):                                  # inputs, within their ranges
            lo, hi = RANGES[name]
            return math.isfinite(value) and lo <= value <= hi
        if self.state not in (INST, INIT):                                # fixed parameters
            return False
        if name == "land_on_communication_points":
            return True
        if name == "x0":
            return math.isfinite(value) and value >= 0
        try:
            P.check_value(name, value)
            return True
        except P.ParameterError:
            return False


REALS = ("voltage", "force", "stroke", "rho_l", "rho_t_s", "x0", "N", None)     # None: an unknown reference
REAL_VALUES = (6000.0, -6000.0, 0.0, 5.0, -50.0, 1e12, 200.0, 1e-4, -1.0, NAN, INF, -INF, 1e300)
CALL = hs.one_of(
    hs.tuples(hs.just("setup"), hs.sampled_from((0.0, 0.5, NAN)), hs.sampled_from((None, 0.05, 1.0, 0.2, -1.0))),
    hs.tuples(hs.sampled_from(("enter", "exit", "terminate", "reset", "get_state", "free_instance"))),
    hs.tuples(hs.just("set_real"), hs.sampled_from(REALS), hs.sampled_from(REAL_VALUES)),
    hs.tuples(hs.just("set_int"), hs.sampled_from(("N", "rho_l", None)), hs.sampled_from((81, 41, 2, -5))),
    hs.tuples(hs.just("set_bool"), hs.sampled_from(("land_on_communication_points", "N")), hs.booleans()),
    hs.tuples(hs.just("set_str"), hs.sampled_from(("scheme", "law", "layout")),
              hs.sampled_from(("paper", "continuum", "linear", "constant", "peano-hasel", "bogus", ""))),
    hs.tuples(hs.just("get_real"), hs.sampled_from(REALS)),
    hs.tuples(hs.just("do_step"), hs.sampled_from(("now", "now", "now", "next", "zero", "nan", "jitter")),
              hs.sampled_from((1e-3, 1e-3, 5e-4, 0.01, 1e-9, 0.0, -1e-3, NAN, INF))),
    hs.tuples(hs.sampled_from(("set_state", "free_state", "serialize")), hs.integers(0, 5)),
    hs.tuples(hs.just("deserialize"), hs.integers(0, 5),
              hs.sampled_from(("none", "none", "flip", "truncate", "extend", "garbage", "empty"))),
)
SETTERS = {"set_real": ("Real", fmi2Real, "fmi2SetReal"), "set_int": ("Integer", fmi2Integer, "fmi2SetInteger"),
           "set_bool": ("Boolean", fmi2Boolean, "fmi2SetBoolean"), "set_str": ("String", fmi2String, "fmi2SetString")}


class Fuzzer:
    def __init__(self, md, unzipped):
        self.md, self.unzipped, self.vr = md, unzipped, vr(md)
        self.kinds = {v.name: v.type for v in md.modelVariables}
        self.logs = []

        def log(env, name, status, cat, msg):
            self.logs.append((status, msg))
        self.callbacks = fmi2CallbackFunctions()          # kept alive with the fuzzer
        self.callbacks.logger = fmi2CallbackLoggerTYPE(log)
        self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(lambda n, size: None)
        self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(lambda p: None)
        self.handles, self.blobs = [], []      # [(pointer value, oracle snapshot, live)], [(bytes, snapshot)]
        self.new_instance()

    def new_instance(self):
        self.s = slave(self.md, self.unzipped, "fuzz", callbacks=self.callbacks)
        self.o = Oracle()

    def invoke(self, fname, *args, logged=True):
        """The status of one of fmpy's bound FMI functions (they raise for Discard and up)."""
        self.logs.clear()
        try:
            status = getattr(self.s, fname)(self.s.component, *args)
        except FMICallException as exc:
            status = exc.status
        FUZZ_STATS["calls"] += 1
        FUZZ_STATS["statuses"][status] = FUZZ_STATS["statuses"].get(status, 0) + 1
        assert status in (OK, WARNING, DISCARD, ERROR), (fname, status)
        assert status != ERROR or self.logs or not logged, f"{fname}: fmi2Error without a log line"
        return status

    def expect(self, name, want, fname, *args):
        state = self.o.state
        got = self.invoke(fname, *args)
        want = want if state in ALLOWED[name] else ERROR
        assert got == want, (name, args, state, got, want, self.logs[-3:])
        return got

    def run(self, c):
        op, o = c[0], self.o
        if op == "setup":
            start, stop = c[1], c[2]
            ok = math.isfinite(start) and (stop is None or stop >= start)
            if self.expect(op, OK if ok else ERROR, "fmi2SetupExperiment", fmi2Boolean(False), fmi2Real(0.0),
                           fmi2Real(start), fmi2Boolean(stop is not None),
                           fmi2Real(0.0 if stop is None else stop)) == OK:
                o.time = o.start = start
                o.stop = stop
        elif op == "enter":
            if self.expect(op, OK, "fmi2EnterInitializationMode") == OK:
                o.state = INIT
        elif op == "exit":
            if self.expect(op, o.exit_status() if o.state == INIT else ERROR, "fmi2ExitInitializationMode") < ERROR:
                o.state = SC
                self.check_outputs()
        elif op == "terminate":
            if self.expect(op, OK, "fmi2Terminate") == OK:
                o.state = TERM
        elif op == "reset":
            if self.expect(op, OK, "fmi2Reset") == OK:
                self.o = Oracle()
        elif op == "free_instance":
            self.s.fmi2FreeInstance(self.s.component)
            # the freed pointer (before anything can reuse its memory): refused, no log to write to
            assert self.invoke("fmi2Terminate", logged=False) == ERROR
            self.new_instance()
            self.handles = [(h, snap, False) for h, snap, _ in self.handles]
        elif op in SETTERS:
            kind, ctype, fname = SETTERS[op]
            name, value = c[1], c[2]
            ok = o.set_ok(name, kind, value, self.kinds)
            arg = (ctype * 1)(value.encode() if kind == "String" else value)
            if self.expect(op, OK if ok else ERROR, fname, self.refs(name), 1, arg) == OK and name in o.params:
                o.params[name] = value
        elif op == "get_real":
            known = c[1] is not None and self.kinds[c[1]] == "Real"
            self.expect(op, OK if known else ERROR, "fmi2GetReal", self.refs(c[1]), 1, (fmi2Real * 1)())
        elif op == "do_step":
            self.do_step(c[1], c[2])
        elif op == "get_state":
            p = fmi2FMUstate()
            if self.expect(op, OK, "fmi2GetFMUstate", byref(p)) == OK:
                self.new_handle(p.value, o.snapshot())
        elif op in ("set_state", "free_state", "serialize"):
            self.state_call(op, c[1])
        else:
            self.deserialize(c[1], c[2])

    def new_handle(self, h, snap):
        # a freed state's address may be handed out again: older entries with that
        # pointer now name the new state
        self.handles = [e for e in self.handles if e[0] != h] + [(h, snap, True)]

    def refs(self, name):
        return (fmi2ValueReference * 1)(self.vr[name] if name is not None else 99999)

    def do_step(self, which, h):
        o = self.o
        t = {"now": o.time, "next": o.time + 1.0, "zero": 0.0, "nan": NAN, "jitter": o.time * (1 + 1e-12)}[which]
        ok = (math.isfinite(t) and math.isfinite(h) and h > 0 and abs(t - o.time) <= 1e-9 * max(1.0, abs(o.time))
              and (o.stop is None or t + h <= o.stop + 1e-9 * max(1.0, abs(o.stop))))
        if self.expect("do_step", OK if ok else ERROR, "fmi2DoStep", fmi2Real(t), fmi2Real(h),
                       fmi2Boolean(True)) == OK:
            o.time = t + h
            self.check_outputs()

    def check_outputs(self):
        y = self.s.getReal([self.vr[k] for k in ("stroke", "velocity", "zipped_length", "zipping_angle",
                                                 "electrostatic_force", "current", "capacitance", "stored_energy")])
        assert all(math.isfinite(v) for v in y), y
        assert 0.0 <= y[0] <= X_E, (y, X_E)

    def state_call(self, op, k):
        h, snap, live = self.handles[k % len(self.handles)] if self.handles else (0xDEAD0, None, False)
        p = fmi2FMUstate(h)                                     # 0xDEAD0: never handed out
        want = OK if live else ERROR
        if op == "set_state":
            if self.expect(op, want, "fmi2SetFMUstate", p) == OK:
                self.o.restore(snap)
        elif op == "free_state":
            if self.expect(op, want, "fmi2FreeFMUstate", byref(p)) == OK:
                assert p.value is None
                self.handles = [(x, s_, lv and x != h) for x, s_, lv in self.handles]
        else:
            size = c_size_t()
            if self.expect(op, want, "fmi2SerializedFMUstateSize", p, byref(size)) == OK:
                buf = create_string_buffer(size.value)
                assert self.expect(op, OK, "fmi2SerializeFMUstate", p, buf, size) == OK
                self.blobs.append((buf.raw, snap))

    def deserialize(self, k, how):
        data, snap = self.blobs[k % len(self.blobs)] if self.blobs else (b"", None)
        m = len(data) // 2
        bad = {"none": data, "flip": data[:m] + bytes([data[m] ^ 1]) + data[m + 1:] if data else b"x",
               "truncate": data[:-7], "extend": data + b"\0", "garbage": b"FMI2PYST" + b"\1" * 90,
               "empty": b""}[how]
        buf = create_string_buffer(bad, max(len(bad), 1))
        p = fmi2FMUstate()
        ok = how == "none" and snap is not None
        if self.expect("deserialize", OK if ok else ERROR, "fmi2DeSerializeFMUstate", buf, len(bad), byref(p)) == OK:
            self.new_handle(p.value, snap)
        else:
            assert p.value is None

    def close(self):
        self.s.fmi2FreeInstance(self.s.component)


@settings(max_examples=300, deadline=None, database=None, suppress_health_check=list(HealthCheck))
@given(calls=hs.lists(CALL, min_size=10, max_size=80))
def _fuzz_sequence(env, calls):
    f = Fuzzer(*env)
    FUZZ_STATS["sequences"] += 1
    # two sequences in three start from a valid run-up, some of them setting a parameter
    # that takes no part (fmi2Warning at exit)
    run_up = [("setup", 0.0, None), ("enter",), ("exit",)]
    if len(calls) % 4 == 1:
        run_up.insert(2, ("set_real", "rho_t_s", 200.0))
    try:
        for c in run_up if len(calls) % 3 else ():
            f.run(c)
        for c in calls:
            f.run(c)
    finally:
        f.close()


def test_fmi_call_sequence_fuzz(md, unzipped):
    """300 random call sequences: the process survives, every status matches
    the oracle, outputs stay finite (asserted call by call)."""
    warnings.simplefilter("ignore", PhysicsWarning)
    before = FUZZ_STATS["sequences"]
    _fuzz_sequence((md, unzipped))
    assert FUZZ_STATS["sequences"] - before >= 200, FUZZ_STATS
    assert all(FUZZ_STATS["statuses"].get(k, 0) > 0 for k in (OK, WARNING, ERROR)), FUZZ_STATS
    print("fuzz statistics:", FUZZ_STATS)


def test_stroke_within_x_e(md, unzipped):
    """The stroke output lies in [0, x_e] (asserted call by call in the fuzz too), in a
    long run with no load, where the front reaches the electrode end."""
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.setReal([r["voltage"], r["force"]], [6000.0, 0.0])       # no load: zips fully in 3 s
    x = []
    for k in range(300):
        s.doStep(k * 0.01, 0.01)
        x.append(s.getReal([r["stroke"]])[0])
    s.freeInstance()
    assert min(x) >= 0 and max(x) <= X_E, (min(x), max(x), X_E)
    assert max(x) > 0.999 * X_E           # it does reach the stop (it ran 1e-7 m past it before)


def test_refused_inputs_keep_the_instance(md, unzipped, capsys):
    """An input beyond its range is refused by fmi2SetReal; a step the model refuses
    before computing (1 MV with b = 1e-6 N s/m: the stroke would cross its range in
    1e-14 s) is fmi2Error without the error state. Either way the instance steps on."""
    names = {v.name: v for v in md.modelVariables}
    assert float(names["voltage"].max) == 1e6 and float(names["force"].min) == -1e6
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.setReal([r["b"]], [1e-6])
    s.exitInitializationMode()
    with pytest.raises(FMICallException) as exc:
        s.setReal([r["voltage"]], [2e6])
    assert exc.value.status == 3 and "expected -1e+06 <= value <= 1e+06" in capsys.readouterr().out
    s.setReal([r["voltage"], r["force"]], [1e6, 0.0])
    with pytest.raises(FMICallException) as exc:
        s.doStep(0.0, H)
    log = capsys.readouterr().out
    assert exc.value.status == 3 and "refused (nothing changed)" in log and "b: 1e-06 N s/m" in log, log
    s.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
    s.doStep(0.0, H)                                   # still stepComplete, at t = 0
    s.doStep(H, H)
    assert s.getReal([r["stroke"]])[0] > 0
    s.terminate()
    s.freeInstance()


# ---------------------------------------------------------------------- targeted
def _raw(s, fname, *args):
    """Status of a bound FMI function (fmpy raises for Discard and up)."""
    try:
        return getattr(s, fname)(s.component, *args)
    except FMICallException as exc:
        return exc.status


@pytest.mark.parametrize("kind", ["vshape", "peano"])
def test_ignored_parameters_warn(md, unzipped, tmp_path, capsys, kind):
    """A parameter that takes no part (parameters.applies), changed from its start value,
    is named in a log line saying it is ignored, and exitInitializationMode returns
    fmi2Warning; unchanged ones are not mentioned."""
    if kind == "peano":
        path = build_fmu(preset("peano-fig10"), tmp_path / "peano.fmu")
        md, unzipped = fmpy.read_model_description(str(path)), fmpy.extract(str(path), str(tmp_path / "unz"))
        changed = {"a": 0.02}
    else:
        changed = {"m_rho": -1e5, "rho_t_s": 200.0}            # law constant, scheme continuum
    r = vr(md)
    for values, want in ((changed, 1), ({}, 0)):
        s = slave(md, unzipped)
        s.setupExperiment(startTime=0.0)
        s.enterInitializationMode()
        for key, value in values.items():
            s.setReal([r[key]], [value])
        capsys.readouterr()
        assert _raw(s, "fmi2ExitInitializationMode") == want
        log = capsys.readouterr().out
        for key in changed:
            assert (f"parameter {key} = " in log and "is ignored" in log) == bool(values), log
        s.doStep(0.0, H)
        s.freeInstance()


def _actuator():
    """The actuator slave in this process (plain Python, no FMU): for the state checks."""
    sys.path.insert(0, str(Path(__file__).parents[1] / "fmu"))
    try:
        from dfa_actuator import DFAActuator
    finally:
        sys.path.pop(0)
    a = DFAActuator(instance_name="direct", resources=None)
    a.setup_experiment(0.0)
    a.exit_initialization_mode()
    a._c_real_buf[:2] = (6000.0, 5.0)
    for k in range(5):
        a.do_step(k * H, H)
    return a


def _bad_states(state):
    """Crafted variants of a valid state, each with one thing wrong."""
    from dfa_model.io import statecodec
    st = state["stepper"]

    def with_solver(i, v):
        return {**state, "stepper": st[:i] + (v,) + st[i + 1:]}
    ist = st[8].copy()
    ist[4] = 1e9                                                    # stuck index far out of range
    return {
        "not a dict": [state],
        "missing key": {k: v for k, v in state.items() if k != "inputs"},
        "parameter out of range": {**state, "params": {**state["params"], "rho_l": -1.0}},
        "float where an integer goes": {**state, "params": {**state["params"], "N": 81.0}},
        "unknown parameter": {**state, "params": {**state["params"], "bogus": 1.0}},
        "NaN input": {**state, "inputs": (float("nan"), 5.0)},
        "inconsistent geometry": {**state, "params": {**state["params"], "a": 0.06}},
        "array of the wrong shape": with_solver(6, np.zeros(3)),
        "array of the wrong dtype": with_solver(6, st[6].astype(np.int64)),
        "NaN in the solver state": with_solver(6, np.full_like(st[6], np.nan)),
        "solver tuple too short": {**state, "stepper": st[:-1]},
        "stuck index out of range": with_solver(8, ist),
        "code instead of data": {**state, "stepper": statecodec},
    }


def test_set_state_is_atomic():
    """A refused state changes nothing: the slave validates all of it before it assigns."""
    from dfa_model.io import statecodec
    a = _actuator()
    good = a._get_fmu_state()
    before = statecodec.encode(good)
    for name, bad in _bad_states(good).items():
        with pytest.raises(ValueError):
            a._set_fmu_state(bad)
        assert statecodec.encode(a._get_fmu_state()) == before, name
    a._set_fmu_state(good)
    assert statecodec.encode(a._get_fmu_state()) == before


def _reframe(data, payload):
    """Serialized bytes with another payload, header length and checksum fixed up (a
    crafted state passes the binary's integrity checks and meets the slave's)."""
    import struct
    import zlib
    head = bytearray(data[:56])
    head[48:56] = struct.pack("<Q", len(payload))
    head[44:48] = struct.pack("<I", zlib.crc32(bytes(head[:44]) + bytes(head[48:]) + payload))
    return bytes(head) + payload


def test_crafted_serialized_states_are_refused(md, unzipped, tmp_path, capsys):
    """Bytes from the host are never unpickled; crafted, truncated, oversized or
    corrupted states are refused with fmi2Error and a message, and the instance goes on."""
    import pickle
    from dfa_model.io import statecodec

    class Boom:
        def __reduce__(self):
            return (open, (str(tmp_path / "pwned"), "w"))
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    s.enterInitializationMode()
    s.exitInitializationMode()
    s.setReal([r["voltage"], r["force"]], [6000.0, 5.0])
    s.doStep(0.0, H)
    data = s.serializeFMUstate(s.getFMUstate())
    assert _reframe(data, data[56:]) == data                   # the test's framing is the binary's
    good = statecodec.decode(data[56:])
    crafted = {name: _reframe(data, statecodec.encode(bad)) for name, bad in _bad_states(good).items()
               if name != "code instead of data"}
    crafted["pickle payload"] = _reframe(data, pickle.dumps(Boom()))
    crafted["pickle as the whole state"] = pickle.dumps(Boom())
    skeleton_deep = b'["L",[' * 200 + b']]' * 200
    crafted["deep nesting"] = _reframe(data, statecodec._HEAD.pack(statecodec.MAGIC, 1, 0, len(skeleton_deep), 0)
                                       + skeleton_deep)
    huge = b'["A","f8",[1000000000,1000000000]]'
    crafted["huge array"] = _reframe(data, statecodec._HEAD.pack(statecodec.MAGIC, 1, 0, len(huge), 0) + huge)
    crafted["oversized length"] = data[:48] + (2 ** 62).to_bytes(8, "little") + data[56:]
    crafted["corrupted"] = data[:100] + bytes([data[100] ^ 0xFF]) + data[101:]
    crafted["truncated"] = data[:-1]
    for name, blob in crafted.items():
        capsys.readouterr()
        with pytest.raises(FMICallException) as exc:
            s.deSerializeFMUstate(blob)
        assert exc.value.status == 3, name
        log = capsys.readouterr().out
        assert "fmi2DeSerializeFMUstate" in log, (name, log)
    assert not (tmp_path / "pwned").exists()
    s.doStep(H, H)                                             # the instance goes on
    s.setFMUstate(s.deSerializeFMUstate(data))                 # and the genuine state still restores
    s.doStep(H, H)
    s.freeInstance()


def test_outputs_cannot_be_set(md, unzipped, capsys):
    """fmi2SetReal on an output is refused in every state, fast path included."""
    r = vr(md)
    s = slave(md, unzipped)
    s.setupExperiment(startTime=0.0)
    for step in ("instantiated", "init", "running"):
        if step == "init":
            s.enterInitializationMode()
        elif step == "running":
            s.exitInitializationMode()
        with pytest.raises(FMICallException):
            s.setReal([r["stroke"]], [1.0])
        assert "it is an output" in capsys.readouterr().out
    assert s.getReal([r["stroke"]])[0] == 0.0
    s.freeInstance()
