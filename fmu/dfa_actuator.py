"""FMI 2.0 co-simulation slave: the actuator (fmu/actuator_core.py) behind pythonfmu's
Fmi2Slave. Only the FMI 2.0 vocabulary lives here; the slave's one implementation is
actuator_core.ActuatorCore, shared with the FMI 3.0 slave (fmu/dfa_actuator3.py).

Copied into the FMU's resources by `dfa fmu build`, beside actuator_core.py. The FMU's
binary is fmu/c/fmi2_loader.c and fmu/c/fmi2_python.c.
"""
if __package__:                  # fmu.dfa_actuator (the source tree)
    from .actuator_core import *  # noqa: F401,F403
    from .actuator_core import (AUTHOR, DESCRIPTION, EXPERIMENT, ActuatorCore, _check_param, _finite,  # noqa: F401
                                _key, _parameters)
else:                            # the FMU's resources (or fmu/ on the path)
    from actuator_core import *  # noqa: F401,F403
    from actuator_core import (AUTHOR, DESCRIPTION, EXPERIMENT, ActuatorCore, _check_param, _finite,  # noqa: F401
                               _key, _parameters)

from pythonfmu.default_experiment import DefaultExperiment  # noqa: E402
from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability  # noqa: E402
from pythonfmu.fmi2slave import Fmi2Slave  # noqa: E402
from pythonfmu.variables import Boolean, Integer, Real, String  # noqa: E402


class FMI2:
    """FMI 2.0's vocabulary (pythonfmu) for ActuatorCore."""
    Real, Integer, Boolean, String = Real, Integer, Boolean, String
    Causality, Variability, Initial, Status = Fmi2Causality, Fmi2Variability, Fmi2Initial, Fmi2Status
    prefix = "fmi2"


class DFAActuator(ActuatorCore, Fmi2Slave):
    FMI = FMI2
    author = AUTHOR
    description = DESCRIPTION
    default_experiment = DefaultExperiment(*EXPERIMENT)
