"""The FMU tests (tests/fmu_cases.py) run in their own pytest process, so that the FMU
binaries they load (and the interpreter state those share) stay out of the main test
process. The results are read from the JUnit report; the process must also exit
cleanly."""
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")


def test_fmu_cases_in_own_process(tmp_path):
    here = Path(__file__).parent
    report = tmp_path / "fmu.xml"
    out = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={report}",
                          str(here / "fmu_cases.py")], capture_output=True, text=True, timeout=1200, cwd=here.parent)
    tail = out.stdout[-4000:] + out.stderr[-2000:]
    assert report.exists(), tail
    suite = ET.parse(report).getroot()
    suite = suite if suite.tag == "testsuite" else suite.find("testsuite")
    assert int(suite.get("tests")) == 48, tail
    assert int(suite.get("failures")) == 0 and int(suite.get("errors")) == 0, tail
    skipped = [case.get("name") for case in suite.iter("testcase") if case.find("skipped") is not None]
    assert skipped == [], (skipped, tail)
    assert out.returncode == 0, tail
