"""The FMUs and the SSP in other tools, where they are installed (skipped otherwise):

- the FMU Compliance Checker: FMUCHECK=/path/to/fmuCheck.linux64, or fmuCheck.linux64
  on PATH: 0 warnings and 0 errors on each of the three FMUs, their XML included;
- OMSimulator: OMSIMULATOR=/path/to/bin/OMSimulator, or OMSimulator on PATH (an
  installation: bin/OMSimulator, lib/<triplet>/libOMSimulator.so and the Python
  package lib/<triplet>/OMSimulator): the SSP opens and runs in its command line, in
  oms_importFile (ctypes) and in its Python SSP class, without a warning or an error,
  and gives fmpy's numbers.

benchmarks/hosts/README.md says which versions were checked. Every tool runs in its own
process (as the FMU tests do: tests/test_fmu.py), fmpy's master included.
"""
import csv
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

T = 3.5        # s: the charge reset's first half-second at 30 Hz, then the DC hold starts moving
H = 1e-3


def _tool(env, name):
    path = os.environ.get(env) or shutil.which(name)
    if not path or not Path(path).is_file():
        pytest.skip(f"{name} not found: set {env}=/path/to/{name} or put it on PATH")
    return Path(path).resolve()


@pytest.fixture(scope="module")
def ssp(tmp_path_factory):
    from dfa_model.cli import main
    out = tmp_path_factory.mktemp("ssp") / "DFASystem.ssp"
    assert main(["fmu", "build", "--preset", "vshape-table1", "--system", "--out", str(out)]) == 0
    return out


@pytest.fixture(scope="module")
def fmus(ssp, tmp_path_factory):
    import zipfile
    folder = tmp_path_factory.mktemp("fmus")
    with zipfile.ZipFile(ssp) as z:
        z.extractall(folder)
    return sorted((folder / "resources").glob("*.fmu"))


@pytest.fixture(scope="module")
def check():
    return _tool("FMUCHECK", "fmuCheck.linux64")


def test_compliance_checker(check, fmus, tmp_path):
    assert len(fmus) == 3
    for fmu in fmus:
        r = subprocess.run([str(check), "-h", "1e-3", "-s", "1", "-o", str(tmp_path / "out.csv"), str(fmu)],
                           capture_output=True, text=True, timeout=600)
        log = r.stdout + r.stderr
        assert r.returncode == 0, log[-3000:]
        assert "Checker reported:\n\t0 Warning(s)\n\t0 Error(s)" in log, (fmu.name, log[-3000:])
        assert "FMU reported:\n\t0 warning(s) and error(s)" in log, (fmu.name, log[-3000:])
        assert "[WARNING]" not in log and "[ERROR]" not in log, (fmu.name, log[-3000:])


@pytest.fixture(scope="module")
def oms():
    """(the OMSimulator executable, libOMSimulator.so beside its Python package)."""
    exe = _tool("OMSIMULATOR", "OMSimulator")
    prefix = exe.parent.parent
    libs = sorted(prefix.glob("lib*/**/libOMSimulator.so"))
    if not libs or not (libs[0].parent / "OMSimulator" / "__init__.py").exists():
        pytest.skip(f"no libOMSimulator.so with its Python package OMSimulator under {prefix}/lib*")
    return exe, libs[0]


def _csv(path):
    """OMSimulator's CSV result: name -> values, one per communication point (it writes
    two rows per point, before and after the inputs are exchanged: the first holds the
    values right after the step), the leading 'model.' of the names dropped."""
    with open(path) as f:
        names = next(csv.reader(f))
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    t = data[:, 0]
    first = np.r_[True, t[1:] != t[:-1]]
    return {n.split(".", 1)[1] if "." in n else n: data[first, i] for i, n in enumerate(names)}


def _run(cmd, cwd, env=None):
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, cwd=cwd, env=env)
    log = r.stdout + r.stderr
    assert r.returncode == 0, log[-4000:]
    return log


def test_ssp_in_omsimulator_as_in_fmpy(oms, ssp, tmp_path):
    """Each of OMSimulator's paths opens the SSP (oms_importFile needs the SSD's
    org.openmodelica annotation, fmu/ssp.py) and runs T s at 1 ms; the stroke, the
    drive's voltage and the load's force are fmpy's master's to rounding (fmpy's row k
    holds the values after the step from t_k, OMSimulator's point k + 1)."""
    exe, lib = oms
    env = dict(os.environ, LD_LIBRARY_PATH=os.pathsep.join([str(lib.parent), os.environ.get("LD_LIBRARY_PATH", "")]),
               PYTHONPATH=os.pathsep.join([str(lib.parent), os.environ.get("PYTHONPATH", "")]))
    runs = {}
    # 1. the command line (oms_RunFile: oms_importFile, then the flags)
    (tmp_path / "cli").mkdir()
    runs["command line"] = _run([str(exe), str(ssp), f"--stopTime={T}", "-r=res.csv"], tmp_path / "cli", env)
    # 2. oms_importFile through the C API (OMEdit's path, OMSimulator 2.x's Python API)
    (tmp_path / "capi").mkdir()
    script = textwrap.dedent(f"""
        import ctypes
        lib = ctypes.CDLL({str(lib)!r})
        lib.oms_setStopTime.argtypes = [ctypes.c_char_p, ctypes.c_double]
        cref = ctypes.c_char_p()
        def call(name, *args):
            status = getattr(lib, name)(*args)
            if status != 0:
                raise SystemExit(f"{{name}}: status {{status}}")
        call("oms_importFile", {str(ssp)!r}.encode(), ctypes.byref(cref))
        model = cref.value
        call("oms_setResultFile", model, b"res.csv", 1)
        call("oms_setStopTime", model, {T!r})
        for name in ("oms_instantiate", "oms_initialize", "oms_simulate", "oms_terminate", "oms_delete"):
            call(name, model)
        """)
    runs["oms_importFile"] = _run([sys.executable, "-c", script], tmp_path / "capi", env)
    # 3. the Python SSP class (OMSimulator 3)
    (tmp_path / "python").mkdir()
    script = textwrap.dedent(f"""
        from OMSimulator import SSP
        model = SSP({str(ssp)!r}).instantiate()
        model.setResultFile("res.csv")
        model.setStopTime({T!r})
        model.setFixedStepSize({H!r})
        model.initialize()
        model.simulate()
        model.terminate()
        model.delete()
        """)
    runs["Python SSP"] = _run([sys.executable, "-c", script], tmp_path / "python", env)
    # fmpy's master, in its own process
    script = textwrap.dedent(f"""
        import warnings
        import numpy as np
        from fmpy.ssp.simulation import simulate_ssp
        warnings.simplefilter("ignore")
        r = simulate_ssp({str(ssp)!r}, stop_time={T!r}, step_size={H!r})
        np.save("fmpy.npy", r)
        """)
    _run([sys.executable, "-c", script], tmp_path)
    ref = np.load(tmp_path / "fmpy.npy")
    n = int(round(T / H))
    assert len(ref) == n + 1 and np.max(ref["actuator.stroke"]) > 5e-4
    folders = {"command line": "cli", "oms_importFile": "capi", "Python SSP": "python"}
    for path, log in runs.items():
        for line in log.splitlines():
            # "could not load the ssd schema file": an installation without the schema
            # folder beside the binary skips OMSimulator's own SSD validation
            assert not line.startswith(("error", "warning")) or "could not load the ssd schema" in line, (path, line)
        assert "Alg. loop" not in log, (path, log[-3000:])
        res = _csv(tmp_path / folders[path] / "res.csv")
        col = {k.replace("DFASystem.", ""): v for k, v in res.items()}
        assert len(col["time"]) == n + 1 and col["time"][-1] == pytest.approx(T)
        for sig in ("actuator.stroke", "drive.voltage", "load.force", "actuator.capacitance"):
            diff = np.max(np.abs(col[sig][1:] - ref[sig][:-1]))
            assert diff <= 1e-9 * np.max(np.abs(ref[sig])), (path, sig, diff)
