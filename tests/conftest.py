import os
import tempfile
import warnings

import pytest

from dfa_model import preset


@pytest.fixture(scope="session")
def vshape():
    return preset("vshape-table1")


@pytest.fixture(scope="session")
def vshape81():
    """The default discretization (N = 81), named for the tests that rely on its N."""
    return preset("vshape-table1").replace(N=81)


@pytest.fixture(scope="session")
def peano():
    return preset("peano-fig10")


# surrogates `dfa design`/`dfa hold` fit and cache (reduced/model_cache.py): one cache for the
# session, never the user's (commands in subprocesses inherit it)
os.environ["DFA_SURROGATE_CACHE"] = tempfile.mkdtemp(prefix="dfa_surrogates_")


@pytest.fixture(autouse=True)
def _quiet_physics_warnings():
    from dfa_model import PhysicsWarning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicsWarning)
        yield


def pytest_terminal_summary(terminalreporter):
    """How the kernels ran (compiled at install, or by numba in each process: slower, and
    a sign the build could not compile them), and the fuzz suite's counts
    (tests/fuzz_support.py), when it ran."""
    from dfa_model import _jit
    terminalreporter.write_line(f"dfa_model kernels: {_jit.MODE} ({_jit.__file__})")
    try:
        from fuzz_support import COUNTS
    except ImportError:
        return
    if COUNTS:
        kinds = ", ".join(f"{k[6:]} {v}" for k, v in sorted(COUNTS.items()) if k.startswith("cases:"))
        terminalreporter.write_line(
            f"fuzz: {COUNTS['cases']} cases ({kinds}): {COUNTS['clean errors']} clean errors, {COUNTS['results']} "
            f"results ({COUNTS['with warnings']} with warnings), {COUNTS['partial results (exit 1)']} partial "
            f"results (exit 1: a sweep's failed runs, a design with nothing to write); 0 tracebacks, internal "
            f"errors or NaN (else a test failed)")
        for k, v in sorted(COUNTS.items()):
            if k.startswith(("errors:", "results:")):
                terminalreporter.write_line(f"fuzz:   {k} {v}")
