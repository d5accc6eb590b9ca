"""FMI 3.0 co-simulation slave: the actuator (fmu/actuator_core.py) behind pythonfmu3's
Fmi3Slave. Only the FMI 3.0 vocabulary lives here (Float64 and Int32 variables, the
independent variable `time`); the slave's one implementation is
actuator_core.ActuatorCore, shared with the FMI 2.0 slave (fmu/dfa_actuator.py).

Copied into the FMU's resources by `dfa fmu build --fmi 3`, beside actuator_core.py
(pythonfmu3's Python package comes inside the FMU). The FMU's binary is
fmu/c/fmi3_loader.c and fmu/c/fmi3_python.c (pythonfmu3's own is replaced: see there).
"""
if __package__:                  # fmu.dfa_actuator3 (the source tree)
    from .actuator_core import *  # noqa: F401,F403
    from .actuator_core import AUTHOR, DESCRIPTION, EXPERIMENT, ActuatorCore
else:                            # the FMU's resources (or fmu/ on the path)
    from actuator_core import *  # noqa: F401,F403
    from actuator_core import AUTHOR, DESCRIPTION, EXPERIMENT, ActuatorCore

from pythonfmu3.default_experiment import DefaultExperiment  # noqa: E402
from pythonfmu3.enums import Fmi3Causality, Fmi3Initial, Fmi3Status, Fmi3Variability  # noqa: E402
from pythonfmu3.fmi3slave import Fmi3Slave  # noqa: E402
from pythonfmu3.variables import Boolean, Float64, Int32, String  # noqa: E402

MODEL_IDENTIFIER = "DFAActuator"    # the same model as the FMI 2.0 FMU: the same name


class FMI3:
    """FMI 3.0's vocabulary (pythonfmu3) for ActuatorCore."""
    Real, Integer, Boolean, String = Float64, Int32, Boolean, String
    Causality, Variability, Initial, Status = Fmi3Causality, Fmi3Variability, Fmi3Initial, Fmi3Status
    prefix = "fmi3"


class DFAActuator3(ActuatorCore, Fmi3Slave):
    FMI = FMI3

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        # pythonfmu3 reads these from the instance (its __init__ sets them to None)
        self.modelName = MODEL_IDENTIFIER
        self.author, self.description = AUTHOR, DESCRIPTION
        self.default_experiment = DefaultExperiment(*EXPERIMENT)

    def _register_independent(self):
        # FMI 3.0: exactly one independent variable (value reference 0)
        self.register_variable(Float64("time", causality=Fmi3Causality.independent,
                                       variability=Fmi3Variability.continuous,
                                       description="simulation time [s] (the last communication point reached)"))

    @property
    def time(self) -> float:
        """The current communication point: the start time before the first step."""
        self._sync()
        return self._start_time if self._stepper is None else float(self._stepper.t)
