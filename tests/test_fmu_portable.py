"""The FMU away from the project: a fresh virtual environment (no system site-packages)
with only the FMU's runtime dependencies and fmpy, no dfa_model, no pythonfmu.

- fmpy in that environment runs a copy of the FMU, and its stroke is that of
  `dfa simulate` on the same protocol;
- a C host (tests/fmu_host.c) runs it against that environment, named by
  DFA_FMU_PYTHON, and gives the model's stroke;
- an environment without NumPy, or a path with no Python, fails instantiation with a
  log line that says what to install or set.

COST: one module-scoped environment, `python -m venv --without-pip` + this interpreter's
`pip install --python ENV --no-compile` of numpy, scipy, numba and fmpy at this
environment's versions (from the pip cache when warm; about 19 s here), plus one without
pip (2 s). Skipped, with pip's message, when pip cannot install
them (no package index and no cache).
"""
import csv
import os
import shutil
import subprocess
import sys
import warnings
from importlib import metadata
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

from dfa_model import PhysicsWarning, preset  # noqa: E402
from dfa_model.numerics.stepper import Stepper  # noqa: E402
from fmu_support import H, direct_stroke  # noqa: E402

RUNTIME = ("numpy", "scipy", "numba", "fmpy")
needs_linux = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the FMU is built for Linux")


def _clean_env(**extra):
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "LD_PRELOAD", "LD_LIBRARY_PATH", "DFA_FMU_PYTHON", "VIRTUAL_ENV")}
    env.update(extra)
    return env


@pytest.fixture(scope="module")
def fresh_env(tmp_path_factory):
    env = tmp_path_factory.mktemp("fresh") / "env"
    # no pip of its own: this interpreter's pip installs into it (--python), and without
    # compiling every module of SciPy and numba ahead (--no-compile): 19 s instead of 40-49 s
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(env)], check=True, capture_output=True,
                   timeout=300)
    pins = [f"{name}=={metadata.version(name)}" for name in RUNTIME]
    r = subprocess.run([sys.executable, "-m", "pip", "--python", str(env / "bin" / "python"), "install", "-q",
                        "--no-compile", *pins], capture_output=True, text=True, timeout=900, env=_clean_env())
    if r.returncode != 0:
        pytest.skip(f"pip could not install {' '.join(pins)}: {r.stderr.strip()[-500:]}")
    return env


@pytest.fixture(scope="module")
def fmu_in_env(fresh_env):
    from fmu import build_fmu
    return build_fmu(preset("vshape-table1"), fresh_env / "DFAActuator.fmu")


def _py(env, code, **kw):
    return subprocess.run([str(env / "bin" / "python"), "-c", code], capture_output=True, text=True, timeout=600,
                          env=_clean_env(), cwd=env, **kw)


@needs_linux
def test_fresh_env_has_only_the_runtime(fresh_env):
    for name in ("dfa_model", "fmu", "pythonfmu", "reduced"):
        r = _py(fresh_env, f"import {name}")
        assert r.returncode != 0 and "ModuleNotFoundError" in r.stderr, name


@needs_linux
def test_fmpy_in_fresh_env_gives_the_stroke_of_dfa_simulate(fresh_env, fmu_in_env, tmp_path):
    """Charge reset (30 Hz, 0.3 s) then 0.3 s DC at 6 kV, 5 N: through fmpy.simulate_fmu
    in the fresh environment (its switches are input events, so communication points)
    and through `dfa simulate` here. The solver's states are the same, so the final
    stroke agrees to rounding; at the 1 ms points in between, the FMU reads points just
    before a switch off a step the switch then cuts short: within the local error bound
    rtol (x_e + x)."""
    code = f"""
import numpy as np, fmpy
half = 1 / 60
t, v = [0.0], [6000.0]
for k in range(1, 18):
    t += [k * half, k * half]; v += [v[-1], -6000.0 if k % 2 else 6000.0]
t += [0.3, 0.3, 0.6]; v += [v[-1], 6000.0, 6000.0]
inp = np.array([(a, b, 5.0) for a, b in zip(t, v)], dtype=[('time', float), ('voltage', float), ('force', float)])
r = fmpy.simulate_fmu({str(fmu_in_env)!r}, stop_time=0.6, output_interval=1e-3, input=inp, output=['stroke'])
np.savetxt('fmpy_stroke.txt', np.column_stack([r['time'], r['stroke']]))
"""
    r = _py(fresh_env, code)
    assert r.returncode == 0, r.stderr[-3000:]
    fmu = np.loadtxt(fresh_env / "fmpy_stroke.txt")
    out = tmp_path / "sim.csv"
    dfa = shutil.which("dfa", path=str(Path(sys.executable).parent)) or "dfa"
    sim = subprocess.run([dfa, "simulate", "--preset", "vshape-table1", "--voltage", "6000", "--force", "5",
                          "--reset", "0.3", "--duration", "0.3", "--out", str(out)], capture_output=True, text=True,
                         timeout=600)
    assert sim.returncode == 0, sim.stderr
    with open(out) as f:
        rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
    col = rows[0]
    ref = np.array([[float(x[col.index("time")]), float(x[col.index("stroke")])] for x in rows[1:]])
    # the FMU's value at each 1 ms point (after any event rows at the same time)
    at = {round(t, 9): x for t, x in fmu}
    x_fmu = np.array([at[round(t, 9)] for t in ref[:, 0]])
    assert np.max(ref[:, 1]) > 5e-4
    assert abs(x_fmu[-1] - ref[-1, 1]) <= 1e-9 * ref[-1, 1]
    p, x_e = preset("vshape-table1"), Stepper(preset("vshape-table1")).model.kin.x_e
    assert np.max(np.abs(x_fmu - ref[:, 1])) <= p.rtol * (x_e + np.max(ref[:, 1]))


def _c_host(tmp_path, fmu, python, nsteps=200):
    import fmpy
    exe = tmp_path / "fmu_host"
    cc = subprocess.run(["gcc", "-O1", "-o", str(exe), str(Path(__file__).with_name("fmu_host.c")), "-ldl"],
                        capture_output=True, text=True)
    assert cc.returncode == 0, cc.stderr
    md = fmpy.read_model_description(str(fmu))
    d = Path(fmpy.extract(str(fmu), str(tmp_path / "unz")))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    so = d / "binaries" / "linux64" / f"{md.coSimulation.modelIdentifier}.so"
    return subprocess.run([str(exe), str(so), (d / "resources").as_uri(), md.guid, str(vr["voltage"]),
                           str(vr["force"]), str(vr["stroke"]), str(nsteps), str(H)], capture_output=True,
                          text=True, timeout=600, env=_clean_env(DFA_FMU_PYTHON=str(python)))


@needs_linux
@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_c_host_runs_against_the_named_env(fresh_env, fmu_in_env, tmp_path):
    """DFA_FMU_PYTHON names the fresh environment: the C host's interpreter takes its
    site-packages (the model's copy comes from the FMU) and steps as the model does."""
    out = _c_host(tmp_path, fmu_in_env, fresh_env)
    lines = out.stdout.split("\n")
    assert out.returncode == 0 and lines[0].startswith("stroke"), out.stdout + out.stderr[-3000:]
    warnings.simplefilter("ignore", PhysicsWarning)
    x = float(lines[0].split()[1])
    assert x > 5e-4 and abs(x - direct_stroke(200)) <= 1e-12 * x


@needs_linux
@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_missing_dependency_or_python_fails_instantiation_saying_what_to_do(fresh_env, fmu_in_env, tmp_path):
    """An environment without NumPy: fmi2Instantiate returns NULL (fmi2Error logged)
    naming what to pip install; a path without a Python, or a Python without its shared
    library: the log says so and what to install or set."""
    bare = tmp_path / "bare"
    subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(bare)], check=True, timeout=300)
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
    out = _c_host(tmp_path / "a", fmu_in_env, bare)
    assert out.returncode == 4 and "instantiate failed" in out.stdout, out.stdout + out.stderr
    log = out.stderr
    assert "[host 3 logStatusError]" in log and "cannot import numpy" in log, log
    assert "pip install" in log and "'numpy>=" in log and str(bare) in log, log
    out = _c_host(tmp_path / "b", fmu_in_env, tmp_path / "nowhere")
    assert out.returncode == 4 and "DFA_FMU_PYTHON" in out.stderr and "no Python there" in out.stderr, out.stderr
    # an environment whose base Python has no shared library (here: none at all): the
    # loader (fmu/c/fmi2_loader.c) cannot load libpython and says what to install
    fake = tmp_path / "fake"
    (fake / "bin").mkdir(parents=True)
    (fake / "bin" / "python3").write_text("#!/bin/sh\n")
    (fake / "pyvenv.cfg").write_text(f"home = {tmp_path / 'no-python' / 'bin'}\nversion = 3.11.0\n")
    (tmp_path / "c").mkdir()
    out = _c_host(tmp_path / "c", fmu_in_env, fake)
    assert out.returncode == 4 and "needs its shared library libpython" in out.stderr, out.stderr
    assert "install CPython" in out.stderr and "DFA_FMU_PYTHON" in out.stderr, out.stderr
