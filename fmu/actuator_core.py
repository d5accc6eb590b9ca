"""The actuator slave's one implementation, shared by the FMI 2.0 FMU (fmu/dfa_actuator.py,
pythonfmu's Fmi2Slave) and the FMI 3.0 FMU (fmu/dfa_actuator3.py, pythonfmu3's Fmi3Slave):
the continuum DFA model (dfa_model) behind either API.

ActuatorCore holds all of it: the variables (registered through the adapter's FMI
vocabulary, `FMI`: its variable classes and enumerations), the parameters' checks, the
stepping, the fast-path buffers the binary reads and writes (fmu/c/fmi2_python.c, which
fmi3_python.c builds on), and the FMU state. An adapter only names its FMI version's
vocabulary and base class; neither adds behaviour.

This file is copied into the FMU's resources by `dfa fmu build`, beside the adapter, with
the parameter file the FMU was built from (dfa_params.toml) and a copy of the model
package itself, resources/_dfa_model (the same code as `dfa simulate`, with its kernels
compiled ahead of time): the FMU runs in any Python with its runtime dependencies
(RUNTIME.txt: NumPy; numba where the compiled kernels do not fit that Python; SciPy for
the spline law), whether or not the project is installed there, and always runs its own
copy. Run from the source tree (pythonfmu imports it at build time) it uses the
installed dfa_model. It imports neither pythonfmu nor pythonfmu3.

Inputs (held between communication points; a change is a jump at the step start):
voltage (V), force (N, opposing zipping). Errors (bad parameters, solver failure) are
raised here; the binary logs the message and returns an error status. The binary keeps
the FMI state machine and checks the calls' arguments (states, value references, NaN,
step sizes, times) before this class sees them.

FMU states are plain data (dicts, tuples, floats, NumPy arrays), serialized with
dfa_model.io.statecodec (never pickle: the bytes come from the host), and validated in full
before anything is assigned, so a refused state changes nothing.
"""
import importlib
import math
import os
import sys

_here = os.path.dirname(os.path.abspath(__file__))
BUNDLED = "_dfa_model"        # the FMU's copy of dfa_model (fmu/build.py)


def _runtime_requirements():
    try:
        with open(os.path.join(_here, "RUNTIME.txt")) as f:
            return " ".join(repr(line.strip()) for line in f if line.strip() and not line.startswith("#"))
    except OSError:
        return "numpy scipy numba"


def _import_model():
    """(numpy, the model package): the bundled copy beside this file, else the installed
    dfa_model. A missing dependency is an ImportError that says what to install where
    (the binary logs it: instantiation fails with an error status)."""
    try:
        import numpy
        if os.path.isdir(os.path.join(_here, BUNDLED)):
            pkg = importlib.import_module(BUNDLED)
        else:
            pkg = importlib.import_module("dfa_model")
        mods = {sub.rpartition(".")[2]: importlib.import_module(f"{pkg.__name__}.{sub}")
                 for sub in ("limits", "io.parameters", "io.statecodec", "numerics.stepper")}
        return numpy, pkg, mods
    except ImportError as exc:
        missing = exc.name or str(exc)
        raise ImportError(
            f"DFAActuator: cannot import {missing} in the Python that runs the FMU ({sys.executable}, Python "
            f"{sys.version.split()[0]}): install the FMU's runtime dependencies there: python -m pip install "
            f"{_runtime_requirements()} (numba only where the FMU's precompiled kernels do not fit: "
            f"{getattr(exc, 'msg', exc)})") from None


np, _model, _mods = _import_model()
limits, P, statecodec = _mods["limits"], _mods["parameters"], _mods["statecodec"]
INPUT_RTOL, OUTPUTS, Stepper = _mods["stepper"].INPUT_RTOL, _mods["stepper"].OUTPUTS, _mods["stepper"].Stepper

PARAMS_FILE = "dfa_params.toml"
STEP_HEAD = 10     # header of _c_step_buf (fmi2_python.c, fast_step)

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
EXTRA = {  # FMU-only parameters, not keys of the parameter file: (range and unit, start)
    "x0": (P.Spec("fmu", "m", "initial stroke", 0.0, lo_incl=True), 0.0),
    "v_nominal": (P.Spec("fmu", "V", "nominal voltage amplitude: sets the charge scale of the error control", 0.0),
                  6000.0),
}
INPUT_INFO = {
    "voltage": ("V", "voltage across the electrodes"),
    "force": ("N", "external load force, opposing zipping"),
}
# [min, max] of the inputs (dfa_model.limits): build.py writes them into the model
# description, the binary refuses a value outside them (fmi2SetReal, fmi3SetFloat64)
RANGES = {kind: (-bound, bound) for kind, (bound, _) in limits.SIGNALS.items()}
# [min, max] of the parameters (None: unbounded), from the checks their setters make
# (dfa_model.io.parameters.SPEC, EXTRA): build.py writes them into the model description.
# FMI's min and max are inclusive: a bound the check excludes (l > 0) is written as the
# min all the same, and the setter refuses the bound itself.
PARAM_RANGES = {key: (spec.lo, spec.hi) for key, spec in (*P.SPEC.items(), *((k, e[0]) for k, e in EXTRA.items()))
                if spec.kind is not str and (spec.lo is not None or spec.hi is not None)}
# every parameter variable, in registration order (the FMU state holds them by name)
PARAM_KEYS = ("layout", *P.SPEC, "land_on_communication_points", *EXTRA)
STATE_KEYS = ("params", "inputs", "experiment", "stepper")
# the unit of every Real variable (build.py writes them into modelDescription.xml)
UNITS = {**{k: u for k, (u, _) in INPUT_INFO.items()}, **{k: u for k, (u, _) in OUTPUT_INFO.items()},
         **{k: s.unit for k, s in P.SPEC.items() if s.unit}, **{k: e[0].unit for k, e in EXTRA.items()}}


AUTHOR = "dfa-toolkit"
DESCRIPTION = ("Dielectric fluid actuator (HASEL, Peano-HASEL, V-shaped zipping pouch): continuum model of the "
               "Maxwell-Wagner-Sillars charge relaxation coupled to the stroke")
EXPERIMENT = (0.0, 23.0, 1e-3)    # the default experiment: start, stop, step size (the standard protocol)


class ActuatorCore:
    """The actuator slave, whatever the FMI version. A subclass (the adapter) also derives
    from its pythonfmu base class and sets FMI, its version's vocabulary: an object with
    the variable classes Real, Integer, Boolean and String (pythonfmu3: Float64, Int32,
    Boolean, String), the enumerations Causality, Variability, Initial and Status, and
    `prefix`, the API's function prefix ("fmi2" or "fmi3", in messages)."""
    FMI = None

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        V = self.FMI
        here = self.resources or os.path.dirname(os.path.abspath(__file__))
        path = os.path.join(here, PARAMS_FILE)
        base = P.load(path) if os.path.exists(path) else P.Parameters()
        self._c_real_buf = np.zeros(len(FAST))      # voltage, force, outputs (properties below)
        # the solver step the binary may answer communication points from (fast_step in
        # fmi2_python.c): header, the two inputs, then a, b, c of the outputs
        self._c_step_buf = np.zeros(STEP_HEAD + 2 + 3 * len(OUTPUTS))
        self.land_on_communication_points = False
        self._start_time, self._stop_time = 0.0, None
        self._stepper = None
        self._stepper_key = None        # the parameters and experiment the stepper was built for
        self._templates = {}            # parameters -> structure of their stepper states
        self._register_independent()
        for name, (unit, text) in INPUT_INFO.items():
            var = V.Real(name, causality=V.Causality.input, variability=V.Variability.continuous,
                         description=f"{text} [{unit}]", setter=self._input_setter(name))
            var.min, var.max = RANGES[name]          # read by the binary (fast-path bounds)
            self.register_variable(var)
        for name, (unit, text) in OUTPUT_INFO.items():
            self.register_variable(V.Real(name, causality=V.Causality.output, variability=V.Variability.continuous,
                                          initial=V.Initial.calculated, description=f"{text} [{unit}]"))
        # parameters: every key of the parameter file, start values from the built file
        self.layout = base.layout
        self.register_variable(V.String("layout", causality=V.Causality.parameter,
                                        variability=V.Variability.fixed, initial=V.Initial.exact,
                                        description="layout: " + " or ".join(P.LAYOUTS),
                                        setter=self._param_setter("layout")))
        for key, spec in P.SPEC.items():
            value = getattr(base, key)
            if value is None:            # a / volume of the other layout: unused
                value = 0.0
            setattr(self, key, value)
            kind = {float: V.Real, int: V.Integer, str: V.String}[spec.kind]
            unit = f" [{spec.unit}]" if spec.unit else ""
            self.register_variable(kind(key, causality=V.Causality.parameter, variability=V.Variability.fixed,
                                        initial=V.Initial.exact,
                                        description=f"{spec.table}: {spec.description}{unit}; {spec.range_text()}",
                                        setter=self._param_setter(key)))
        self.register_variable(V.Boolean(
            "land_on_communication_points", causality=V.Causality.parameter, variability=V.Variability.fixed,
            initial=V.Initial.exact, setter=self._param_setter("land_on_communication_points"),
            description="false (default): the solver steps across communication points while the inputs stay the "
                        "same and interpolates there (its steps are those of dfa simulate with the same input "
                        "switches); true: every communication point ends a solver step (the trajectory of dfa "
                        "simulate with the input sampled at every point; 10-50x slower at 1 ms steps)"))
        vr = {v.name: v.value_reference for v in self.vars.values()}
        self._c_real_vrs = tuple(vr[name] for name in FAST)
        for key, (spec, start) in EXTRA.items():
            setattr(self, key, start)
            self.register_variable(V.Real(key, causality=V.Causality.parameter, variability=V.Variability.fixed,
                                          initial=V.Initial.exact, description=f"{spec.description} [{spec.unit}]",
                                          setter=self._param_setter(key)))
        self._start_values = self._param_values()

    def _register_independent(self):
        """The variables registered before the actuator's (FMI 3.0: the independent
        variable, time)."""

    # ------------------------------------------------------------------ setters
    def _param_setter(self, key):
        return lambda v: self._set_param(key, v)

    def _input_setter(self, name):
        return lambda v: self._set_input(name, v)

    def _set_param(self, key, value):
        if self._stepper is not None:    # the binary refuses this already (fixed parameters)
            raise ValueError(f"{key}: parameters are fixed after initialization (reset the FMU to change them)")
        _check_param(key, value)
        setattr(self, key, value)

    def _set_input(self, name, value):
        if not math.isfinite(value):
            raise ValueError(f"{name}: got {value!r}, expected a finite number")
        setattr(self, name, value)

    # ------------------------------------------------------------------ life cycle
    def _param_values(self) -> dict:
        return {key: getattr(self, key) for key in PARAM_KEYS}

    def setup_experiment(self, start_time, stop_time=None, tolerance=None):
        self._start_time = float(start_time)
        self._stop_time = None if stop_time is None else float(stop_time)

    def _new_stepper(self, params: dict, experiment: tuple) -> Stepper:
        start, stop = experiment
        stop = stop if stop is not None and stop > start else None
        return Stepper(_parameters(params), v_nominal=params["v_nominal"], x0=params["x0"], t0=start, t_end=stop,
                       exact=params["land_on_communication_points"])

    def exit_initialization_mode(self):
        params, experiment = self._param_values(), (self._start_time, self._stop_time)
        try:
            stepper = self._new_stepper(params, experiment)
        except (P.ParameterError, ValueError) as exc:
            raise ValueError(f"initialization failed: {exc}") from None
        self._stepper, self._stepper_key = stepper, _key(params, experiment)
        self._publish()
        self._warn_ignored(params)

    def _warn_ignored(self, params):
        """Parameters changed from their start value that take no part in the model
        (parameters.applies): a warning each, so that the call returns a warning status."""
        for key in P.SPEC:
            if not P.applies(self, key) and params[key] != self._start_values[key]:
                self.log(f"{self.FMI.prefix}ExitInitializationMode: parameter {key} = {params[key]!r} is ignored: it "
                         f"takes no part with layout {self.layout!r}, scheme {self.scheme!r}, law {self.law!r}",
                         self.FMI.Status.warning)

    def do_step(self, current_time, step_size):
        # the binary has checked the state, the time (continues the run) and step_size > 0
        st = self._stepper
        if st is None:
            raise RuntimeError("do_step before exit_initialization_mode")
        st.t = current_time          # the master's clock is the reference
        self._c_step_buf[0] = 0.0    # until the step is done (a failed one leaves nothing to reuse)
        buf = self._c_real_buf
        st.step(step_size, buf[0], buf[1])
        self._publish()
        return True

    def _publish(self):
        st = self._stepper
        self._c_real_buf[2:] = st.out
        sb = self._c_step_buf
        poly = st.interpolant()
        if poly is None:
            sb[0] = 0.0
            return
        t0, h, a, b, c, reached = poly
        n = len(OUTPUTS)
        sb[1:STEP_HEAD] = (t0, h, reached, 0.0, st.model.kin.x_e, st.t, 2, n, INPUT_RTOL)
        sb[STEP_HEAD:STEP_HEAD + 2] = (st.V, st.F)
        k = STEP_HEAD + 2
        sb[k:k + n], sb[k + n:k + 2 * n], sb[k + 2 * n:k + 3 * n] = a, b, c
        sb[0] = 1.0

    def _sync(self):
        """Take over the communication time and outputs of the steps the binary took in C
        (fast_step): the stepper's own copy stops at its last Python step."""
        st = self._stepper
        if st is not None and self._c_step_buf[0] == 1.0 and self._c_step_buf[6] != st.t:
            st.t = float(self._c_step_buf[6])
            st.out = self._c_real_buf[2:].copy()

    # ------------------------------------------------------------------ FMU state
    @staticmethod
    def _fmu_state_to_bytes(state):
        return statecodec.encode(state)

    @staticmethod
    def _fmu_state_from_bytes(data):
        return statecodec.decode(data)

    def _get_fmu_state(self):
        self._sync()
        return {"params": self._param_values(), "inputs": (self.voltage, self.force),
                "experiment": (self._start_time, self._stop_time),
                "stepper": None if self._stepper is None else self._stepper.get_state()}

    def _set_fmu_state(self, state):
        # validate everything, then assign: a refused state changes nothing
        params, inputs, experiment, stepper, solver_state = self._validate_fmu_state(state)
        if stepper is not None:
            stepper.set_state(solver_state)
        for key, value in params.items():
            setattr(self, key, value)
        self._c_real_buf[:2] = inputs
        self._start_time, self._stop_time = experiment
        self._stepper = stepper
        self._stepper_key = None if stepper is None else _key(params, experiment)
        if stepper is None:
            self._c_real_buf[2:] = 0.0
            self._c_step_buf[0] = 0.0
        else:
            self._publish()

    def _validate_fmu_state(self, state):
        """The parts of `state` ready to assign, after the checks a live state passes:
        every parameter through parameters' validation, the inputs finite, the solver
        state of the structure of a freshly built one (statecodec.check_like) and with
        values the solver accepts (Stepper.check_state). Raises ValueError naming the
        first problem. Also called by the binary right after fmi2DeSerializeFMUstate."""
        where = "FMU state"
        if not isinstance(state, dict) or set(state) != set(STATE_KEYS):
            raise ValueError(f"{where}: expected a dict with keys {', '.join(STATE_KEYS)}")
        params = state["params"]
        if not isinstance(params, dict) or set(params) != set(PARAM_KEYS):
            raise ValueError(f"{where}: params must name every parameter ({', '.join(PARAM_KEYS)})")
        for key in PARAM_KEYS:
            _check_param(key, params[key])
        inputs = state["inputs"]
        if not (isinstance(inputs, tuple) and len(inputs) == 2 and all(_finite(v) for v in inputs)):
            raise ValueError(f"{where}: inputs must be (voltage, force), finite numbers")
        experiment = state["experiment"]
        if not (isinstance(experiment, tuple) and len(experiment) == 2 and _finite(experiment[0])
                and (experiment[1] is None or _finite(experiment[1]))):
            raise ValueError(f"{where}: experiment must be (start time, stop time or None), finite")
        solver_state = state["stepper"]
        if solver_state is None:
            return params, inputs, experiment, None, None
        key = _key(params, experiment)
        if self._stepper is not None and self._stepper_key == key:
            stepper = self._stepper                     # same set-up: reuse (assigned only after the checks)
        else:
            try:
                stepper = self._new_stepper(params, experiment)
            except (P.ParameterError, ValueError) as exc:
                raise ValueError(f"{where}: {exc}") from None
        statecodec.check_like(solver_state, self._template(params, experiment), f"{where}: solver state")
        try:
            stepper.check_state(solver_state)
        except ValueError as exc:
            raise ValueError(f"{where}: solver state: {exc}") from None
        return params, inputs, experiment, stepper, solver_state

    def _template(self, params, experiment):
        """The structure of every solver state for these parameters: a fresh stepper's
        state and one after a free step (which fills the optional entries)."""
        key = _key(params, experiment)
        if key not in self._templates:
            fresh = self._new_stepper(params, experiment)
            stepped = self._new_stepper({**params, "land_on_communication_points": False}, experiment)
            stepped.step(1e-9, 0.0, 0.0)
            self._templates = {key: statecodec.template(fresh.get_state(), stepped.get_state())}
        return self._templates[key]


def _finite(v):
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _key(params, experiment):
    return tuple(params[k] for k in PARAM_KEYS) + tuple(experiment)


def _check_param(key, value):
    """Raise ParameterError unless `value` is a valid value of parameter `key`, of the
    variable's type (a state from outside must not smuggle in a float N or a string x0)."""
    if key == "land_on_communication_points":
        if not isinstance(value, bool):
            raise P.ParameterError(f"{key}: got {value!r}, expected true or false")
    elif key in EXTRA:
        P.check_value(key, value, EXTRA[key][0])
    elif key in ("a", "volume") and _finite(value) and value == 0.0:
        pass                          # the other layout's key: 0 = unused
    else:
        if key != "layout" and P.SPEC[key].kind is int and (isinstance(value, bool) or not isinstance(value, int)):
            raise P.ParameterError(f"{key}: got {value!r}, expected {P.SPEC[key].range_text()}")
        P.check_value(key, value)


def _parameters(params: dict) -> P.Parameters:
    flat = {k: params[k] for k in ("layout", *P.SPEC)}
    flat["volume" if flat["layout"] == "v-shaped" else "a"] = None
    return P.Parameters(**flat)


def _buffered(i, writable):
    def get(self):
        return float(self._c_real_buf[i])

    def put(self, value):
        self._c_real_buf[i] = value
    # outputs have no setter: pythonfmu would otherwise give them one
    return property(get, put if writable else None)


for _i, _name in enumerate(FAST):
    setattr(ActuatorCore, _name, _buffered(_i, _name in INPUT_INFO))
