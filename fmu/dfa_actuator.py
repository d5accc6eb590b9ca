"""FMI 2.0 co-simulation slave: the continuum DFA model (dfa_model) behind pythonfmu.

This file is copied into the FMU's resources by `dfa fmu build`, with the parameter file
the FMU was built from (dfa_params.toml). It imports the installed `dfa_model`: the FMU
runs the same code as `dfa simulate`.

Inputs (held between communication points; a change is a jump at the step start):
voltage (V), force (N, opposing zipping). Errors (bad parameters, NaN inputs, solver
failure) are logged and returned as fmi2Error; the master may roll back with
fmi2SetFMUstate.
"""
import os
import sys

_here = os.path.dirname(os.path.abspath(__file__))


def _promote_libpython():
    """In a C host, libpython arrives as a NEEDED library of the FMU binary, loaded
    RTLD_LOCAL: extension modules (math, NumPy) then cannot resolve its symbols. Loading
    it once more with RTLD_GLOBAL promotes it. This runs before any extension module is
    imported, so it may use builtins only: _imp.create_dynamic dlopens with the current
    flags and then fails to find an init function, which is expected."""
    path_file = os.path.join(_here, "dfa_libpython.txt")
    if not os.path.exists(path_file):
        return
    path = open(path_file).read().strip()
    if not os.path.exists(path):
        return
    import _imp

    class Spec:
        name = "_dfa_libpython_global"
        origin = path

    flags = sys.getdlopenflags()
    sys.setdlopenflags(os.RTLD_NOW | os.RTLD_GLOBAL)
    try:
        _imp.create_dynamic(Spec())
    except ImportError:
        pass
    finally:
        sys.setdlopenflags(flags)


_promote_libpython()
if os.path.exists(os.path.join(_here, "dfa_sys_path.txt")):
    # the build's site-packages (a C host embeds the base interpreter, not a venv)
    for _p in open(os.path.join(_here, "dfa_sys_path.txt")).read().split():
        if _p not in sys.path:
            sys.path.append(_p)

import math  # noqa: E402

from pythonfmu.enums import Fmi2Causality, Fmi2Initial, Fmi2Status, Fmi2Variability
from pythonfmu.fmi2slave import Fmi2Slave
from pythonfmu.variables import Integer, Real, String
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
        self.voltage = 0.0
        self.force = 0.0
        for name in OUTPUTS:
            setattr(self, name, 0.0)
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
        self.log(msg, Fmi2Status.error)
        raise ValueError(msg)

    def _set_param(self, key, value):
        if self._stepper is not None:
            self._error(f"{key}: parameters are fixed after initialization (reset the FMU to change them)")
        if key == "layout" or (key in P.SPEC and P.SPEC[key].kind is str):
            # pythonfmu 0.7 crashes the host if a String setter raises: take the value,
            # log the problem now and fail fmi2ExitInitializationMode, which names the key
            setattr(self, key, value)
            try:
                P.check_value(key, value)
            except P.ParameterError as exc:
                self.log(str(exc), Fmi2Status.error)
            return
        try:
            if key in EXTRA:
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

    def exit_initialization_mode(self):
        try:
            params = self._parameters()
            self._stepper = Stepper(params, v_nominal=self.v_nominal, x0=self.x0)
        except (P.ParameterError, ValueError) as exc:
            self._error(f"initialization failed: {exc}")
        self._publish()

    def do_step(self, current_time, step_size):
        st = self._stepper
        if st is None:
            self._error("doStep called before initialization")
        if self._failed:
            self._error("the solver failed at an earlier step; restore a saved state or reset")
        st.t = current_time          # the master's clock is the reference
        try:
            st.step(step_size, self.voltage, self.force)
        except Exception as exc:     # SolverError, ValueError: reported, never a crash
            self._failed = True
            self._error(f"doStep at t = {current_time:g} s: {exc}")
        self._publish()
        return True

    def _publish(self):
        row = self._stepper.outputs
        for name in OUTPUTS:
            setattr(self, name, row[name])

    # ------------------------------------------------------------------ FMU state
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
                saved = Stepper(self._parameters(), v_nominal=self.v_nominal, x0=self.x0)
            self._stepper = saved
            self._stepper.set_state(st)
        self._failed = failed
