"""FMI 2.0 co-simulation slave: the continuum DFA model (dfa_model) behind pythonfmu.

This file is copied into the FMU's resources by `dfa fmu build`, with the parameter file
the FMU was built from (dfa_params.toml). It imports the installed `dfa_model`: the FMU
runs the same code as `dfa simulate`. The FMU's binary is fmu/c/fmi2_python.c.

Inputs (held between communication points; a change is a jump at the step start):
voltage (V), force (N, opposing zipping). Errors (bad parameters, NaN inputs, solver
failure) are raised here; the binary logs the message and returns fmi2Error, and the
master may roll back with fmi2SetFMUstate or reset.
"""
import os
import sys

_here = os.path.dirname(os.path.abspath(__file__))


if os.path.exists(os.path.join(_here, "dfa_sys_path.txt")):
    # the build's site-packages (a C host embeds the base interpreter, not a venv)
    for _p in open(os.path.join(_here, "dfa_sys_path.txt")).read().split():
        if _p not in sys.path:
            sys.path.append(_p)

import math  # noqa: E402
import pickle  # noqa: E402

import numpy as np  # noqa: E402

from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Boolean, Integer, Real, String
from pythonfmu.default_experiment import DefaultExperiment

from dfa_model import parameters as P
from dfa_model.stepper import OUTPUTS, Stepper

PARAMS_FILE = "dfa_params.toml"

OUTPUT_INFO = {
    "stroke": ("m", "stroke x (vertical travel of the load)"),
    "velocity": ("m/s", "stroke velocity dx/dt"),
    "zipped_length": ("m", "zipped length l_z"),
    "zipping_angle": ("rad", "zipping angle theta (Eq. 18; Peano-HASEL: half curvature angle)"),
    "electrostatic_force": ("N", "electrostatic zipping force -F_e"),
    "current": ("A", "current drawn from the source (between voltage jumps)"),
    "capacitance": ("F", "capacitance of the actuator"),
    "stored_energy": ("J", "electrostatic energy stored in the actuator"),
}
# the Real variables the binary reads and writes directly (see fmi2_python.c)
FAST = ("voltage", "force", *OUTPUTS)
EXTRA = {  # FMU-only parameters: not keys of the parameter file
    "x0": ("m", "initial stroke", 0.0),
    "v_nominal": ("V", "nominal voltage amplitude: sets the charge scale of the error control", 6000.0),
}
INPUT_INFO = {
    "voltage": ("V", "voltage across the electrodes"),
    "force": ("N", "external load force, opposing zipping"),
}
# the unit of every Real variable (build.py writes them into modelDescription.xml)
UNITS = {**{k: u for k, (u, _) in INPUT_INFO.items()}, **{k: u for k, (u, _) in OUTPUT_INFO.items()},
         **{k: s.unit for k, s in P.SPEC.items() if s.unit}, **{k: e[0] for k, e in EXTRA.items()}}


class DFAActuator(Fmi2Slave):
    author = "dfa-toolkit"
    description = ("Dielectric fluid actuator (HASEL, Peano-HASEL, V-shaped zipping pouch): continuum model of "
                   "the Maxwell-Wagner-Sillars charge relaxation coupled to the stroke")
    default_experiment = DefaultExperiment(start_time=0.0, stop_time=23.0, step_size=1e-3)

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        here = self.resources or os.path.dirname(os.path.abspath(__file__))
        path = os.path.join(here, PARAMS_FILE)
        base = P.load(path) if os.path.exists(path) else P.Parameters()
        self._c_real_buf = np.zeros(len(FAST))      # voltage, force, outputs (properties below)
        self.land_on_communication_points = True
        self._start_time, self._stop_time = 0.0, None
        self._stepper = None
        self._failed = False
        for name, (unit, text) in INPUT_INFO.items():
            self.register_variable(Real(name, causality=Fmi2Causality.input, variability=Fmi2Variability.continuous,
                                        description=f"{text} [{unit}]", setter=self._input_setter(name)))
        for name, (unit, text) in OUTPUT_INFO.items():
            self.register_variable(Real(name, causality=Fmi2Causality.output, variability=Fmi2Variability.continuous,
                                        initial=Fmi2Initial.calculated, description=f"{text} [{unit}]"))
        # parameters: every key of the parameter file, start values from the built file
        self.layout = base.layout
        self.register_variable(String("layout", causality=Fmi2Causality.parameter,
                                      variability=Fmi2Variability.fixed, initial=Fmi2Initial.exact,
                                      description="layout: " + " or ".join(P.LAYOUTS),
                                      setter=self._param_setter("layout")))
        for key, spec in P.SPEC.items():
            value = getattr(base, key)
            if value is None:            # a / volume of the other layout: unused
                value = 0.0
            setattr(self, key, value)
            kind = {float: Real, int: Integer, str: String}[spec.kind]
            unit = f" [{spec.unit}]" if spec.unit else ""
            self.register_variable(kind(key, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact,
                                        description=f"{spec.table}: {spec.description}{unit}; {spec.range_text()}",
                                        setter=self._param_setter(key)))
        self.register_variable(Boolean(
            "land_on_communication_points", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
            initial=Fmi2Initial.exact, setter=self._param_setter("land_on_communication_points"),
            description="true: every communication point ends a solver step (the trajectory of dfa simulate on the "
                        "same sampled input); false: the solver steps across communication points while the inputs "
                        "stay the same and interpolates there (same error control; much faster at small steps)"))
        vr = {v.name: v.value_reference for v in self.vars.values()}
        self._c_real_vrs = tuple(vr[name] for name in FAST)
        for key, (unit, text, start) in EXTRA.items():
            setattr(self, key, start)
            self.register_variable(Real(key, causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed,
                                        initial=Fmi2Initial.exact, description=f"{text} [{unit}]",
                                        setter=self._param_setter(key)))

    # ------------------------------------------------------------------ setters
    def _param_setter(self, key):
        return lambda v: self._set_param(key, v)

    def _input_setter(self, name):
        return lambda v: self._set_input(name, v)

    def _error(self, msg):
        raise ValueError(msg)       # the binary logs it and returns fmi2Error

    def _set_param(self, key, value):
        if self._stepper is not None:
            self._error(f"{key}: parameters are fixed after initialization (reset the FMU to change them)")
        try:
            if key == "land_on_communication_points":
                value = bool(value)
            elif key in EXTRA:
                if not math.isfinite(value) or value < 0 or (key == "v_nominal" and value <= 0):
                    raise P.ParameterError(f"{key}: got {value!r}, expected a finite number "
                                           f"{'> 0' if key == 'v_nominal' else '>= 0'} ({EXTRA[key][0]})")
            elif not (key in ("a", "volume") and value == 0.0):
                P.check_value(key, value)
        except P.ParameterError as exc:
            self._error(str(exc))
        setattr(self, key, value)

    def _set_input(self, name, value):
        if not math.isfinite(value):
            self._error(f"{name}: got {value!r}, expected a finite number")
        setattr(self, name, value)

    # ------------------------------------------------------------------ life cycle
    def _parameters(self):
        flat = {"layout": self.layout}
        for key in P.SPEC:
            flat[key] = getattr(self, key)
        if flat["layout"] == "v-shaped":
            flat["volume"] = None
        else:
            flat["a"] = None
        return P.Parameters(**flat)

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = float(start_time)
        self._stop_time = None if stop_time is None else float(stop_time)

    def _new_stepper(self):
        stop = self._stop_time if self._stop_time is not None and self._stop_time > self._start_time else None
        return Stepper(self._parameters(), v_nominal=self.v_nominal, x0=self.x0, t0=self._start_time, t_end=stop,
                       exact=self.land_on_communication_points)

    def exit_initialization_mode(self):
        try:
            self._stepper = self._new_stepper()
        except (P.ParameterError, ValueError) as exc:
            self._error(f"initialization failed: {exc}")
        self._publish()

    def do_step(self, current_time, step_size):
        st = self._stepper
        if st is None:
            self._error("doStep called before initialization")
        if self._failed:
            self._error("the solver failed at an earlier step; restore a saved state or reset")
        if abs(current_time - st.t) > 1e-9 * max(1.0, abs(st.t)):
            self._error(f"doStep: currentCommunicationPoint = {current_time!r} s, expected the end of the previous "
                        f"step, {st.t!r} s")
        st.t = current_time          # the master's clock is the reference
        buf = self._c_real_buf
        try:
            st.step(step_size, buf[0], buf[1])
        except Exception as exc:     # SolverError, ValueError: reported, never a crash
            self._failed = True
            self._error(f"doStep at t = {current_time:g} s: {exc}")
        self._publish()
        return True

    def _publish(self):
        self._c_real_buf[2:] = self._stepper.out

    # ------------------------------------------------------------------ FMU state
    # the state holds NumPy arrays: pickle, not pythonfmu's JSON
    @staticmethod
    def _fmu_state_to_bytes(state):
        return pickle.dumps(state)

    @staticmethod
    def _fmu_state_from_bytes(data):
        return pickle.loads(data)

    def _get_fmu_state(self):
        state = super()._get_fmu_state()
        state["_stepper"] = None if self._stepper is None else self._stepper.get_state()
        state["_failed"] = self._failed
        return state

    def _set_fmu_state(self, state):
        state = dict(state)
        st, failed = state.pop("_stepper"), state.pop("_failed")
        saved, self._stepper = self._stepper, None          # let parameter setters through
        super()._set_fmu_state(state)
        if st is not None:
            if saved is None:
                saved = self._new_stepper()
            self._stepper = saved
            self._stepper.set_state(st)
        self._failed = failed


def _buffered(i):
    def get(self):
        return float(self._c_real_buf[i])

    def put(self, value):
        self._c_real_buf[i] = value
    return property(get, put)


for _i, _name in enumerate(FAST):
    setattr(DFAActuator, _name, _buffered(_i))
