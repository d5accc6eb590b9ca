"""Run through tests/test_fmu.py, in a separate process. The FMU: build, validation, fmpy simulation against the direct model, life cycle,
state rollback, error paths, a C host, and loading a copy in a fresh process."""
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
from fmpy.fmi2 import FMU2Slave  # noqa: E402

from dfa_model import PhysicsWarning, Protocol, preset, simulate  # noqa: E402
from dfa_model.stepper import Stepper  # noqa: E402
from dfa_model.waveforms import Sampled  # noqa: E402
from fmu import build_fmu  # noqa: E402

H = 1e-3


@pytest.fixture(scope="module")
def fmu_path(tmp_path_factory):
    return build_fmu(preset("vshape-table1"), tmp_path_factory.mktemp("fmu") / "DFAActuator.fmu")


@pytest.fixture(scope="module")
def md(fmu_path):
    return fmpy.read_model_description(str(fmu_path))


@pytest.fixture(scope="module")
def unzipped(fmu_path, tmp_path_factory):
    return fmpy.extract(str(fmu_path), str(tmp_path_factory.mktemp("unz")))


def vr(md):
    return {v.name: v.valueReference for v in md.modelVariables}


def slave(md, unzipped, name="a"):
    s = FMU2Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
                  instanceName=name)
    s.instantiate()
    return s


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


def direct_stroke(nsteps, voltage=6000.0, force=5.0):
    """Stroke after nsteps steps of H, computed by the model directly (no FMU)."""
    st = Stepper(preset("vshape-table1"), v_nominal=6000.0)
    for _ in range(nsteps):
        st.step(H, voltage, force)
    return st.outputs["stroke"]


def bipolar(n, v=6000.0, period_steps=34):
    return np.where((np.arange(n) // (period_steps // 2)) % 2 == 0, v, -v)


def test_validates_and_documents(fmu_path, md):
    assert fmpy.validation.validate_fmu(str(fmu_path)) == []
    names = {v.name: v for v in md.modelVariables}
    for out in ("stroke", "velocity", "zipped_length", "zipping_angle", "electrostatic_force", "current",
                "capacitance", "stored_energy"):
        assert names[out].causality == "output" and names[out].description
    assert names["voltage"].causality == "input" and names["voltage"].unit == "V"
    assert names["rho_l"].causality == "parameter" and names["rho_l"].variability == "fixed"
    assert float(names["rho_l"].start) == preset("vshape-table1").rho_l and names["rho_l"].unit == "ohm m"
    assert names["N"].type == "Integer" and names["scheme"].type == "String"
    assert float(md.defaultExperiment.stopTime) == 23.0
    with zipfile.ZipFile(fmu_path) as z:
        assert "resources/dfa_params.toml" in z.namelist()


def test_matches_direct_model(md, unzipped):
    """Same sampled input (bipolar 30 Hz, then DC): stroke within 1e-6 of `simulate`."""
    warnings.simplefilter("ignore", PhysicsWarning)
    n = 600
    V = np.concatenate([bipolar(300), np.full(n - 300, 6000.0)])
    x = fmu_stroke(md, unzipped, V, reals={"v_nominal": 6000.0})
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


def test_free_stepping_is_accurate(md, unzipped):
    """land_on_communication_points = false: the solver steps across communication
    points. Its outputs stay as close to a tight-tolerance reference as simulate's."""
    warnings.simplefilter("ignore", PhysicsWarning)
    n = 400
    V = bipolar(n)
    x = fmu_stroke(md, unzipped, V, booleans={"land_on_communication_points": False}, stop_time=n * H)
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
    assert abs(x - direct_stroke(200)) <= 1e-9 * abs(x)


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
    for f in (drive, load):
        assert fmpy.validation.validate_fmu(str(f)) == []
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
