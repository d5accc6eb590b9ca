"""The FMU tests (tests/fmu_cases.py) run in their own pytest process, so that the FMU
binaries they load (and the interpreter state those share) stay out of the main test
process. The results are read from the JUnit report; the process must also exit
cleanly (tests/fmu_support.py, run_cases)."""
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu")

from fmu_support import run_cases  # noqa: E402


def test_fmu_cases_in_own_process(tmp_path):
    run_cases("fmu_cases.py", 48, tmp_path)
