"""`dfa fmu build --system --drive DRIVE.toml`: the system's drive FMU plays a protocol
file (README, 'FMU', the SSP paragraph). The FMUs are built and run through fmpy in a
child process (as tests/test_fmu.py runs its cases), so that their binaries stay out of
this one; the comparisons with the model run here."""
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import warnings
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np
import pytest

fmpy = pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")
if not (os.environ.get("CC") or any(shutil.which(c) for c in ("cc", "gcc", "clang"))):
    pytest.skip("needs a C compiler (the FMUs' binary is compiled at build time)", allow_module_level=True)
if not sysconfig.get_config_var("Py_ENABLE_SHARED"):
    pytest.skip("needs a Python with its shared library (the FMUs embed it)", allow_module_level=True)

import fmpy.validation  # noqa: E402

from dfa_model import PhysicsWarning, preset, simulate  # noqa: E402
from dfa_model.cli import main  # noqa: E402
from dfa_model.physics.model import DFAModel  # noqa: E402
from dfa_model.waveforms import Load, Protocol, Sampled  # noqa: E402

# 0.2 s of 30 Hz inversion with 0.3 ms ramps (12 kV at 4e7 V/s), then a DC hold, against 5 N
DRIVE = """\
[[stage]]
name = "reset"
waveform = "bipolar"
voltage = 6000.0
frequency = 30.0
slew_rate = 4e7
duration = 0.2
[[stage]]
name = "hold"
waveform = "dc"
voltage = 6000.0
duration = 0.8
[load]
force = 5.0
"""
SETS = ["--set", "N=21"]
H_DRIVE = 1e-3               # the drive alone
H_SYSTEM = (5e-4, 2.5e-4)    # the system's exchange steps
G = 9.81

CHILD = """
import contextlib, io, json, sys, zipfile
import numpy as np, fmpy
from fmpy.ssp.simulation import simulate_ssp
from dfa_model.cli import main
from fmu import build_companion_fmu
work, drive, D = sys.argv[1], sys.argv[2], float(sys.argv[3])
hs = [float(h) for h in sys.argv[4].split(",")]
ssp = work + "/system.ssp"
msg = io.StringIO()
with contextlib.redirect_stdout(msg):
    rc = main(["fmu", "build", "--system", "--drive", drive, "--set", "N=21", "--out", ssp])
assert rc == 0, rc
build_companion_fmu("drive", work + "/plain_drive.fmu")
build_companion_fmu("load", work + "/plain_load.fmu")
with zipfile.ZipFile(ssp) as z:
    z.extractall(work + "/ssp")
out = {}
# the drive alone, its load_capacitance input at 0, past the protocol's end
r = fmpy.simulate_fmu(work + "/ssp/resources/DriveElectronics.fmu", stop_time=D + 0.05, step_size=%r,
                      output_interval=%r, start_values={"load_capacitance": 0.0},
                      output=["voltage", "supply_current"])
out["drive_t"], out["drive_v"], out["drive_i"] = r["time"], r["voltage"], r["supply_current"]
for k, h in enumerate(hs):
    r = simulate_ssp(ssp, stop_time=D, step_size=h)
    for name in ("time", "drive.voltage", "load.force", "actuator.stroke"):
        out[f"{k}:{name}"] = r[name]
np.savez(work + "/runs.npz", **out)
print(json.dumps({"message": msg.getvalue().strip()}))
""" % (H_DRIVE, H_DRIVE)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    work = tmp_path_factory.mktemp("fmu_drive")
    drive = work / "drive.toml"
    drive.write_text(DRIVE)
    proto = Protocol.from_toml(drive)
    out = subprocess.run([sys.executable, "-c", CHILD, str(work), str(drive), repr(proto.duration),
                          ",".join(map(repr, H_SYSTEM))], capture_output=True, text=True, timeout=600,
                         cwd=Path(__file__).parent.parent)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-3000:]
    data = dict(np.load(work / "runs.npz"))
    return {"work": work, "drive": drive, "proto": proto, "data": data,
            "message": json.loads(out.stdout.strip().splitlines()[-1])["message"]}


def played(proto, t):
    """The protocol's voltage at t, held at its end value after its end."""
    pw = proto.piecewise()
    return pw(np.minimum(t, pw.t[-1]))


def variables(fmu):
    return {v.name: v for v in fmpy.read_model_description(str(fmu)).modelVariables}


def test_drive_fmu_plays_the_protocol(runs):
    """The drive FMU built with the protocol file, alone in fmpy at 1 ms with no load:
    its voltage at every communication point is the protocol's at that time (the
    value it samples at each step end; held after the end), to 1e-9 of the amplitude
    (measured: 0, bit for bit). The limits' start values do not bind: no current
    (load_capacitance 0), and the slew rate lets the full swing pass in 1 ns."""
    d, proto = runs["data"], runs["proto"]
    t = d["drive_t"]
    assert t[-1] > proto.duration + 0.04                      # past the end: held
    assert np.max(np.abs(d["drive_v"] - played(proto, t))) <= 1e-9 * 6000.0
    assert d["drive_v"][-1] == proto.piecewise().v0[-1]
    assert np.all(d["drive_i"] == 0.0)
    fmu = runs["work"] / "ssp" / "resources" / "DriveElectronics.fmu"
    assert fmpy.validation.validate_fmu(str(fmu)) == []
    v = variables(fmu)
    assert v["mode"].start == "protocol" and "protocol" in v["mode"].description
    pw = proto.piecewise()
    assert float(v["slew_rate"].start) >= max(12e3 / 1e-9, np.max(np.abs(pw.slope)))
    assert float(v["current_limit"].start) >= float(v["slew_rate"].start) * 1.0     # I / C >= slew for C <= 1 F
    with zipfile.ZipFile(fmu) as z:
        data = json.loads(z.read("resources/drive_protocol.json"))
    assert data["source"] == "drive.toml" and data["duration"] == proto.duration
    assert np.array_equal(data["t"], pw.t) and np.array_equal(data["v0"], pw.v0)


def test_companions_without_drive_are_unchanged(runs):
    """Built without a protocol, the drive and the load are what they were: the same
    modes and start values, no start-value or protocol resources."""
    drive, load = runs["work"] / "plain_drive.fmu", runs["work"] / "plain_load.fmu"
    v = variables(drive)
    assert v["mode"].start == "reset_dc" and v["mode"].description == "waveform: reset_dc, inversion, dc"
    assert {k: float(v[k].start) for k in ("amplitude", "frequency", "reset_time", "slew_rate", "current_limit")} \
        == {"amplitude": 6000.0, "frequency": 30.0, "reset_time": 3.0, "slew_rate": 5e6, "current_limit": 2e-3}
    v = variables(load)
    assert {k: float(v[k].start) for k in ("mass", "stiffness", "damping")} == \
        {"mass": 0.51, "stiffness": 2000.0, "damping": 5.0}
    for fmu in (drive, load):
        with zipfile.ZipFile(fmu) as z:
            names = z.namelist()
        assert "resources/start_values.json" not in names and "resources/drive_protocol.json" not in names


def test_system_plays_the_protocol_in_fmpys_master(runs):
    """fmpy's SSP master (fmpy.ssp.simulation.simulate_ssp) runs the system built with
    --drive for the protocol's duration (the SSD's stopTime), at exchange steps h = 0.5
    and 0.25 ms. Its row k holds the values after the step from t_k; in the step from t_k
    the actuator sees the drive's voltage at t_k (the protocol's) and the load's force
    there, held over the step (0 in the first step: fmpy starts its connectors at 0).

    - The drive's voltage is the protocol's at every step end (1e-9 of the amplitude).
    - The load: a mass F / g on the 2 kN/m spring, so its force at rest is the file's
      F = 5 N (the first row, exactly), and it stays near it (last 0.2 s: mean within
      1e-3 of F; measured 2e-4).
    - On the inputs it saw, the actuator's stroke is simulate's within its local error
      bound rtol (x_e + x) = 0.56 um (measured 0.16 um).
    - Against `dfa simulate --protocol` of the file with the same load (the force the load
      FMU exerted, held over each step as exchanged), only the voltage's exchange
      differs: the exchange holds each switch's sample for a step, so near the 0.3 ms
      ramps the stroke differs by up to 0.19 mm for a moment (a sample at 0 V held for
      a step lets the pouch open at F/b = 0.5 m/s). Each inversion period's mean stroke
      agrees within 0.04 m/s x h (10 um at 0.25 ms; the worst period, measured: 38,
      13.7, 5.4, 2.6 um at h = 1, 0.5, 0.25, 0.125 ms: first order in h), and halving h
      at least nearly halves it (measured 0.39x). In the DC hold from 0.4 s, 0.2 s after
      the last switch, within rtol (x_e + x) (measured 19 nm at 0.25 ms).
    - Against `dfa simulate --protocol` as it runs the file (a constant 5 N): the mass on
      its spring is not a constant force: the zipping at t = 0 (0.86 mm: 1.7 N on the
      spring) sets it swinging at 10 Hz, decaying over 2m/c = 0.2 s, and the period
      means differ by up to 0.14 mm. Over the last 0.2 s (two swings) the swing is
      +-9 mN, the stroke within 2.1 um, its mean within rtol (x_e + x) (measured 86 nm)."""
    warnings.simplefilter("ignore", PhysicsWarning)
    d, proto = runs["data"], runs["proto"]
    assert "playing" in runs["message"] and "drive.toml for 1 s" in runs["message"]
    assert "fmpy.ssp.simulation.simulate_ssp" in runs["message"]
    ssp = runs["work"] / "system.ssp"
    with zipfile.ZipFile(ssp) as z:
        ssd = ET.fromstring(z.read("SystemStructure.ssd"))
    exp = ssd.find("{http://ssp-standard.org/SSP1/SystemStructureDescription}DefaultExperiment")
    assert float(exp.get("stopTime")) == proto.duration
    load_md = variables(runs["work"] / "ssp" / "resources" / "MassSpringLoad.fmu")
    assert float(load_md["mass"].start) == pytest.approx(5.0 / G, rel=1e-15)

    p = preset("vshape-table1").replace(N=21)
    x_e = DFAModel(p).kin.x_e
    T, F, per = proto.duration, proto.load.F, 1.0 / 30.0
    file_run = simulate(p, proto, load=proto.load, t_eval=np.linspace(0.0, T, 8001))   # dfa simulate --protocol
    worst = []
    for k, h in enumerate(H_SYSTEM):
        n = int(round(T / h))
        t_fmpy = d[f"{k}:time"][:n]
        v, f, x = (d[f"{k}:{name}"][:n] for name in ("drive.voltage", "load.force", "actuator.stroke"))
        assert len(d[f"{k}:time"]) >= n
        assert np.max(np.abs(v - played(proto, t_fmpy + h))) <= 1e-9 * 6000.0
        assert abs(f[0] - F) <= 1e-12 * F
        late = slice(int(round(0.8 / h)), n)
        assert abs(np.mean(f[late]) - F) <= 1e-3 * F
        tk = np.arange(n + 1) * h
        t = tk[1:]
        bound = p.rtol * (x_e + np.max(x))
        # the inputs the actuator saw over each step
        v_seen, f_seen = np.concatenate([[0.0], v[:-1]]), np.concatenate([[0.0], f[:-1]])
        seen = simulate(p, Protocol.single(Sampled(tk[:-1], v_seen, hold=True), T),
                        load=Load(Sampled(tk[:-1], f_seen, hold=True)), t_eval=t)
        assert np.max(x) > 5e-4 and np.max(np.abs(x - seen.x)) <= bound
        same_load = simulate(p, proto, load=Load(Sampled(tk[:-1], f_seen, hold=True)), t_eval=t)
        diff = x - same_load.x
        means = [abs(np.mean(diff[(t > i * per) & (t <= (i + 1) * per)])) for i in range(6)]
        worst.append(max(means))
        assert worst[-1] <= 0.04 * h, (h, means)
        assert np.max(np.abs(diff[t > 0.4])) <= bound
        const = x - np.interp(t, file_run.t, file_run.x)
        assert abs(np.mean(const[t > 0.8])) <= bound
    assert worst[1] <= 0.6 * worst[0], worst


def _error(argv, capsys):
    rc = main(argv)
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and err.startswith("dfa: error: "), (rc, err)
    return err


def test_cli_errors(tmp_path, capsys):
    """--drive without --system, a missing file, an unknown key, and loads the system's
    hanging mass cannot be: exit 2, one line naming the flag, file or key; nothing
    written (each fails before building)."""
    out = tmp_path / "s.ssp"
    good = tmp_path / "drive.toml"
    good.write_text(DRIVE)
    err = _error(["fmu", "build", "--drive", str(good), "--out", str(tmp_path / "a.fmu")], capsys)
    assert "--drive" in err and "--system" in err
    err = _error(["fmu", "build", "--system", "--drive", str(tmp_path / "nope.toml"), "--out", str(out)], capsys)
    assert "nope.toml" in err and "not found" in err
    cases = {"bogus": DRIVE.replace("duration = 0.8", "duration = 0.8\nbogus = 1"),
             "k_load": DRIVE + "k_load = 100.0\n",
             "force = 0": DRIVE.replace("force = 5.0", "force = 0.0"),
             "sampled": DRIVE.replace("force = 5.0", "times = [0.0, 1.0]\nvalues = [5.0, 6.0]")}
    for i, (key, text) in enumerate(cases.items()):
        bad = tmp_path / f"bad{i}.toml"
        bad.write_text(text)
        err = _error(["fmu", "build", "--system", "--drive", str(bad), *SETS, "--out", str(out)], capsys)
        assert key in err and (bad.name in err if key == "bogus" else "[load]" in err), err
    assert not out.exists()
