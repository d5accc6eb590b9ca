"""What the FMU tests share. tests/fmu_cases.py (FMI 2.0) and tests/fmu3_cases.py (FMI 3.0)
each run in their own pytest process (run_cases: tests/test_fmu.py, tests/test_fmu3.py);
both import the fixtures md and unzipped (of the FMU their own module-scoped fixture
fmu_path builds) and drive instances through slave and vr. direct_stroke is the model's
stroke without an FMU (also tests/test_fmu_portable.py)."""
import subprocess
import sys
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

import pytest

from dfa_model import preset
from dfa_model.numerics.stepper import Stepper

H = 1e-3          # the communication step size of the FMU tests [s]
HERE = Path(__file__).resolve().parent


def run_cases(module: str, n_cases: int, tmp_path, *options) -> str:
    """Run tests/<module> in its own pytest process (options: pytest's), so that the FMU
    binaries it loads, and the interpreter state those share, stay out of this process:
    all its n_cases tests pass, none is skipped, and the process exits cleanly (read from
    its JUnit report). Returns its standard output."""
    report = tmp_path / (Path(module).stem + ".xml")
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", *options, "-p", "no:cacheprovider",
                          f"--junitxml={report}", str(HERE / module)], capture_output=True, text=True, timeout=1200,
                         cwd=HERE.parent)
    tail = out.stdout[-4000:] + out.stderr[-2000:]
    assert report.exists(), tail
    suite = ET.parse(report).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    assert int(suite.get("tests")) == n_cases, tail
    assert int(suite.get("failures")) == 0 and int(suite.get("errors")) == 0, tail
    skipped = [case.get("name") for case in suite.iter("testcase") if case.find("skipped") is not None]
    assert skipped == [], (skipped, tail)
    assert out.returncode == 0, tail
    return out.stdout


# ------------------------------------------------------------------ fixtures (need fmu_path)
@pytest.fixture(scope="module")
def md(fmu_path):
    """The model description of the module's FMU, as fmpy reads it."""
    import fmpy
    return fmpy.read_model_description(str(fmu_path))


@pytest.fixture(scope="module")
def unzipped(fmu_path, tmp_path_factory):
    """The module's FMU, extracted."""
    import fmpy
    return fmpy.extract(str(fmu_path), str(tmp_path_factory.mktemp("unz")))


# ------------------------------------------------------------------ helpers
def vr(md):
    """Variable name -> value reference."""
    return {v.name: v.valueReference for v in md.modelVariables}


def slave(md, unzipped, name="a", **kw):
    """A new instance of the FMU through fmpy (FMU2Slave or FMU3Slave, by md's FMI
    version), instantiated (kw: instantiate's arguments)."""
    if md.fmiVersion == "3.0":
        from fmpy.fmi3 import FMU3Slave as Slave
    else:
        from fmpy.fmi2 import FMU2Slave as Slave
    s = Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier,
              instanceName=name)
    s.instantiate(**kw)
    return s


def description(path):
    """The root element of the FMU's modelDescription.xml."""
    with zipfile.ZipFile(path) as z:
        return ET.fromstring(z.read("modelDescription.xml"))


def direct_stroke(nsteps, voltage=6000.0, force=5.0, t_end=None):
    """Stroke after nsteps steps of H, computed by the model directly (no FMU), stepping
    as the FMU does by default (free stepping, the master's clock k H, the run's end)."""
    st = Stepper(preset("vshape-table1"), v_nominal=6000.0, t_end=t_end, exact=False)
    for k in range(nsteps):
        st.t = k * H
        st.step(H, voltage, force)
    return st.outputs["stroke"]
