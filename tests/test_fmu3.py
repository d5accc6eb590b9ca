"""The FMI 3.0 FMU's tests (tests/fmu3_cases.py: `dfa fmu build --fmi 3`, fmpy's
validation, the standard protocol against `dfa simulate`, FMU state and serialization,
refused values, unsupported calls, a C host; the FMI 2.0 FMU still the default) run in
their own pytest process, as the FMI 2.0 ones do (tests/test_fmu.py): the FMU binaries
they load, and the interpreter state those share, stay out of the main test process,
which also checks that the process exits cleanly (pythonfmu3's own binary crashes its
host at exit after an error). About 30 s on 2 cores."""
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu3")

N_CASES = 8


def test_fmu3_cases_in_own_process(tmp_path):
    here = Path(__file__).parent
    report = tmp_path / "fmu3.xml"
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-s", "-p", "no:cacheprovider",
                          f"--junitxml={report}", str(here / "fmu3_cases.py")], capture_output=True, text=True,
                         timeout=1200, cwd=here.parent)
    tail = out.stdout[-4000:] + out.stderr[-2000:]
    assert report.exists(), tail
    suite = ET.parse(report).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    assert int(suite.get("tests")) == N_CASES, tail
    assert int(suite.get("failures")) == 0 and int(suite.get("errors")) == 0, tail
    skipped = [case.get("name") for case in suite.iter("testcase") if case.find("skipped") is not None]
    assert skipped == [], (skipped, tail)
    assert out.returncode == 0, tail
    print(next((line for line in out.stdout.splitlines() if line.startswith("standard protocol:")), ""))
