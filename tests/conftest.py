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


@pytest.fixture(autouse=True)
def _quiet_physics_warnings():
    from dfa_model import PhysicsWarning
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicsWarning)
        yield
