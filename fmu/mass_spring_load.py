"""FMI 2.0 co-simulation slave: a load for a DFA (the co-simulation example's third
FMU): a mass hanging from the actuator on a spring, its motion damped (air, guide).

Input: the actuator's stroke x (m, upward). Output: the force on the actuator (N,
opposing zipping) F = m g + k (x - x_m), with the mass at x_m (measured from its rest
position) moving as m x_m'' = k (x - x_m) - c x_m'. At rest F = m g. Integrated with
semi-implicit Euler substeps. The force depends on the stroke, not on its rate: a
rate coupling (a damper between actuator and mass) would enter the explicit exchange
with gain c/dt and make the fixed-step co-simulation unstable.

Start values the build chose (resources/start_values.json: name -> value; the system
built with a drive's [load] force F starts with mass = F / G) are applied at
instantiation through the same checks as a host's set.
"""
import json
import math
import os

from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Real

G = 9.81
START_FILE = "start_values.json"         # start values chosen at build time (fmu/build.py writes it)
PARAMS = {  # name: (unit, description, start, 0 allowed); each is finite and > 0 (or 0 where allowed)
    "mass": ("kg", "load mass", 0.51, False),
    "stiffness": ("N/m", "spring stiffness between actuator and mass", 2000.0, False),
    "damping": ("N s/m", "damping of the mass motion", 5.0, True),
}
# the unit of every Real variable (build.py writes them into modelDescription.xml)
UNITS = {"stroke": "m", "force": "N", "mass_position": "m", **{k: p[0] for k, p in PARAMS.items()}}
# [min, max] (None: unbounded) of the parameters, from the setters' checks (build.py
# writes them into modelDescription.xml; FMI's min is inclusive, a setter refuses 0
# where it must be > 0). The input stroke has no range of its own.
RANGES = {k: (0.0, None) for k in PARAMS}


class MassSpringLoad(Fmi2Slave):
    author = "dfa-toolkit"
    description = "Mass on a spring-damper hanging from the actuator (force opposing zipping)"

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.stroke = 0.0
        self.force = 0.0
        self.mass_position = 0.0
        self._v_m = 0.0
        self.register_variable(Real("stroke", causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                    description="actuator stroke [m]", setter=self._set_stroke))
        self.register_variable(Real("force", causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                    initial=Fmi2Initial.calculated, description="force on the actuator [N]"))
        self.register_variable(Real("mass_position", causality=Fmi2Causality.output,
                                    variability=Fmi2Variability.continuous, initial=Fmi2Initial.calculated,
                                    description="mass position from rest, upward [m]"))
        for name, (unit, text, start, _) in PARAMS.items():
            setattr(self, name, start)
            self.register_variable(Real(name, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]",
                                        setter=self._param_setter(name)))
        path = os.path.join(self.resources, START_FILE) if self.resources else None
        if path and os.path.exists(path):
            with open(path, encoding="utf-8") as f:
                start = json.load(f)
            by_name = {v.name: v for v in self.vars.values()}
            for name, value in start.items():
                if name not in by_name or by_name[name].causality != Fmi2Causality.parameter:
                    raise ValueError(f"resources/{START_FILE}: {name}: not a parameter of this FMU")
                by_name[name].setter(value)

    def _param_setter(self, name):
        def put(value):
            unit, _, _, zero = PARAMS[name]
            if not (math.isfinite(value) and (value > 0 or (zero and value == 0))):
                raise ValueError(f"{name}: got {value!r}, expected a finite number {'>=' if zero else '>'} 0 ({unit})")
            setattr(self, name, value)
        return put

    def _set_stroke(self, value):
        if not math.isfinite(value):
            raise ValueError(f"stroke: got {value!r}, expected a finite number")
        self.stroke = value

    def exit_initialization_mode(self):
        self.force = self.mass * G

    def do_step(self, current_time, step_size):
        x = self.stroke
        n = max(1, math.ceil(step_size / (0.05 * math.sqrt(self.mass / self.stiffness))))
        h = step_size / n
        for _ in range(n):
            f = self.stiffness * (x - self.mass_position) - self.damping * self._v_m
            self._v_m += h * f / self.mass
            self.mass_position += h * self._v_m
        self.force = self.mass * G + self.stiffness * (x - self.mass_position)
        return True
