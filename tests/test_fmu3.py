"""The FMI 3.0 FMU's tests (tests/fmu3_cases.py: `dfa fmu build --fmi 3`, fmpy's
validation, the standard protocol against `dfa simulate`, FMU state and serialization,
refused values, unsupported calls, a C host; the FMI 2.0 FMU still the default) run in
their own pytest process, as the FMI 2.0 ones do (tests/test_fmu.py): the FMU binaries
they load, and the interpreter state those share, stay out of the main test process,
which also checks that the process exits cleanly (pythonfmu3's own binary crashes its
host at exit after an error; tests/fmu_support.py, run_cases). About 30 s on 2 cores."""
import pytest

pytest.importorskip("fmpy")
pytest.importorskip("pythonfmu3")

from fmu_support import run_cases  # noqa: E402

N_CASES = 8


def test_fmu3_cases_in_own_process(tmp_path):
    out = run_cases("fmu3_cases.py", N_CASES, tmp_path, "-s")
    print(next((line for line in out.splitlines() if line.startswith("standard protocol:")), ""))
