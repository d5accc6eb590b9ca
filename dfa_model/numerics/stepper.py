"""Step-by-step simulation with inputs held between calls: the co-simulation interface
(the FMU drives the model through it).

A Stepper carries the complete solver state (states, Newton matrix, step-size
controller) from one call to the next, so stepping through communication points
gives the same trajectory as one `simulate` call over the same piecewise-constant
input, and `get_state` / `set_state` roll it back exactly.
"""
from __future__ import annotations

import math

import numpy as np

from .. import limits
from ..physics.equations import K, R_ANG, R_C, R_FE, R_I, R_LZ, R_U, R_V, R_X
from .integrator import GAMMA, I_HN, I_STOP, I_STUCK, OK, integrate
from ..physics.model import DFAModel
from ..io.parameters import Parameters
from .solver import _STATUS, SolverError, check_mechanics, zip_force_per_volt2

NO_INTERRUPT = np.zeros(1, dtype=np.int64)   # integrate's interrupt flag: a step is short, never stopped


class InputRejected(ValueError):
    """A step refused before anything changed (a bad step size or input, or mechanics
    too fast to resolve at this voltage): the stepper can go on with other inputs.
    `fmi_rejected` tells the FMU binary to return fmi2Error without entering the
    error state (fmu/c/fmi2_python.c)."""

    fmi_rejected = True


# output name -> record column (units: m, m/s, m, rad, N, A, F, J)
OUTPUTS = {"stroke": R_X, "velocity": R_V, "zipped_length": R_LZ, "zipping_angle": R_ANG,
           "electrostatic_force": R_FE, "current": R_I, "capacitance": R_C, "stored_energy": R_U}
COLS = np.array(list(OUTPUTS.values()))
G = GAMMA


class Stepper:
    """Advance an actuator through communication steps.

    stepper = Stepper(params, v_nominal=6000.0)
    stepper.step(1e-3, voltage=6000.0, force=5.0)   # integrate [t, t + 1 ms]
    stepper.outputs["stroke"]

    v_nominal (V) sets the charge scale of the error control (as the protocol amplitude
    does in `simulate`); x0 is the initial stroke (m); t_end, if known, is the end of
    the run (the solver lands on it, as `simulate` does on its duration).

    exact=True: every communication point ends a solver step, as every sample of a
    held input does in `simulate`: the same input gives the same trajectory as
    `simulate`, and the cost grows with the number of communication points.

    exact=False: the solver steps across communication points while the inputs stay the
    same; there the outputs are the quadratic through their values at the solver step's
    start, stage and end. When an input changes at a point the solver has already
    passed, that step is redone from its saved start to end exactly there. The error
    control is the same, and the states after each step are those of `simulate`; the
    outputs inside a step differ from `simulate`'s t_eval outputs within the tolerance.
    The cost then follows the solver's steps, not the communication points."""

    def __init__(self, params: Parameters | DFAModel, *, v_nominal: float = 1000.0, x0: float = 0.0,
                 t0: float = 0.0, t_end: float | None = None, exact: bool = True, rtol: float | None = None,
                 max_steps: int = 1_000_000):
        self.model = params if isinstance(params, DFAModel) else DFAModel(params)
        p = self.model.params
        _finite_positive("v_nominal", v_nominal)
        if not (math.isfinite(x0) and 0.0 <= x0 <= self.model.kin.x_e):
            raise ValueError(f"x0: expected a stroke in [0, {self.model.kin.x_e:g}] m, got {x0!r}")
        if not math.isfinite(t0):
            raise ValueError(f"t0: expected a finite time, got {t0!r}")
        if t_end is not None and not (math.isfinite(t_end) and t_end > t0):
            raise ValueError(f"t_end: expected a finite time > t0 = {t0:g} s, got {t_end!r}")
        self.t_end = None if t_end is None else float(t_end)
        self.exact = bool(exact)
        self.rtol = p.rtol if rtol is None else float(rtol)
        self.max_steps = int(max_steps)
        self._scale = self.model.scales(v_nominal)
        self._xc = self.model.force_jumps()
        self._c_zip = zip_force_per_volt2(self.model)
        self._checked = (0.0, 0.0)       # inputs last found resolvable (check_mechanics)
        self.n_steps = 0
        self.t = float(t0)               # communication time
        self.V = 0.0                     # inputs applied up to t (uncharged start)
        self.F = 0.0
        # solver: state y at its own time ts >= t, reached with the voltage V_sol
        self.ts = self.t
        self.y = self.model.initial_state(x0)
        self.V_sol = 0.0
        self._ws, self._ist = self.model.workspace(1e-6)
        # free stepping: the solver state at the start of its last step (t, y, ist, ws,
        # V_prev), for a redo; None when the solver sits exactly at t. Never modified once
        # taken, so saved states share it (as they share _poly)
        self._snap = None
        row, _ = self.model.diagnostics(self.y, 0.0, 0.0)
        row[R_X] = self.y[0]
        self.out = row[COLS]             # the outputs at t, in OUTPUTS order
        self._poly = None                # free stepping: (t_start, h, a, b, c) of the last step

    # ------------------------------------------------------------------ stepping
    def step(self, dt: float, voltage: float, force: float = 0.0) -> None:
        """Integrate from t to t + dt with the voltage (V) and the force (N, opposing
        zipping) held constant; a change from the previous inputs is a jump at t (inputs
        within INPUT_RTOL of the previous ones are taken as unchanged)."""
        try:
            _finite_positive("dt", dt)
            V = limits.signal_value("voltage", voltage)
            F = limits.signal_value("force", force)
            if (V, F) != self._checked:
                check_mechanics(self.model, self.model.mat[K], abs(V), F, self._c_zip)
                self._checked = (V, F)
        except ValueError as exc:         # nothing has changed yet
            raise InputRejected(str(exc)) from None
        # a master's interpolation between equal samples jitters by an ulp or so (fmpy
        # hands over 6000 +- 9e-13 V): below INPUT_RTOL a difference is no change
        V = self.V if same_input(V, self.V) else V
        F = self.F if same_input(F, self.F) else F
        target = self.t + dt
        if self.exact:
            rec, _ = self._integrate(np.array([self.t, target]), V, F, np.array([target]), False)
            self.ts, self.V_sol = target, V
            self.out = rec[-1, COLS]
            self.t, self.V, self.F = target, V, F
            return
        if (V != self.V or F != self.F) and self.ts > self.t:
            self._redo()
        while self.ts < target:
            self._snap = (self.ts, self.y.copy(), self._ist.copy(), tuple(a.copy() for a in self._ws), self.V_sol)
            # one solver step, free to pass t + dt (but landing on the end of the run)
            t_stop = max(target, self.ts + 1e3 if self.t_end is None else self.t_end)
            rec, stats = self._integrate(np.array([self.ts, t_stop]), V, F, np.empty(0), True)
            tp, self.ts, self.V_sol = self.ts, stats[5], V
            # quadratic a + b s + c s^2 through the nodes s = 0, gamma, 1 of the step
            v0, v1, v2 = rec[0, COLS], rec[1, COLS], rec[2, COLS]
            c = ((v1 - v0) - G * (v2 - v0)) / (G * G - G)
            self._poly = (tp, self.ts - tp, v0, v2 - v0 - c, c)
        tp, h, a, b, c = self._poly
        sv = (target - tp) / h
        self.out = a + sv * (b + sv * c)
        self.out[0] = min(max(self.out[0], 0.0), self.model.kin.x_e)   # the interpolant past a stop
        self.t, self.V, self.F = target, V, F

    def _redo(self):
        """An input changes at t inside the solver's last step: take that step again
        from its start, ending exactly at t."""
        tp, yp, ist, ws, V_prev = self._snap
        self._ist[:] = ist
        for a, b in zip(self._ws, ws):
            a[...] = b
        self.y = yp.copy()
        self.V_sol = V_prev
        self._integrate(np.array([tp, self.t]), self.V, self.F, np.empty(0), False)
        self.ts = self.t
        self.V_sol = self.V
        self._snap = None

    def _integrate(self, seg_t, V, F, t_out, one_step):
        m = self.model
        rec, _, stats, y_end, _ = integrate(
            m.cfg, m.geo, m.mat, m.law.law_id, m.law.params, self.y, seg_t, np.array([V]), np.zeros(1),
            np.array([F]), np.zeros(1), self.V_sol, self.rtol, self._scale, t_out, False, False, self.max_steps,
            self._xc, self._ws, self._ist, one_step, False, 1 << 40, NO_INTERRUPT)
        if int(stats[4]) != OK:
            raise SolverError(f"step: stopped at t = {stats[5]:.9g} s on the way from {seg_t[0]:.9g} s to "
                              f"{seg_t[-1]:.9g} s because {_STATUS[int(stats[4])]}; restore a saved state or reset")
        self.y = y_end
        self.n_steps += int(stats[0])
        return rec, stats

    def interpolant(self):
        """(t0, h, a, b, c, t_reached) while the next communication points can be
        answered without the solver: free stepping, with the outputs at t0 + s h being
        a + s (b + s c) (stroke clamped to [0, x_e]) up to t_reached, as long as the inputs
        stay self.V, self.F. None when the next step needs the solver (exact stepping, or
        no solver step taken since the start or a redo). The FMU's binary steps on this
        in C (fmu/c/fmi2_python.c, fast_step)."""
        if self.exact or self._poly is None or self.ts <= self.t:
            return None
        return (*self._poly, self.ts)

    @property
    def outputs(self) -> dict:
        """The outputs at the current time (SI units; see OUTPUTS)."""
        return dict(zip(OUTPUTS, self.out.tolist()))

    def output(self, name: str) -> float:
        return float(self.out[list(OUTPUTS).index(name)])

    # ------------------------------------------------------------------ state
    def get_state(self) -> tuple:
        """A copy of everything the next step depends on."""
        return (self.t, self.V, self.F, self.ts, self.V_sol, self.n_steps, self.y.copy(), self.out.copy(),
                self._ist.copy(), tuple(a.copy() for a in self._ws), self._snap, self._poly)

    def check_state(self, state: tuple) -> None:
        """Raise ValueError if `state`, of get_state's structure (checked by the caller,
        e.g. dfa_model.io.statecodec.check_like), holds values the compiled solver must not
        be given: it indexes the force jumps with the stuck index and steps with the next
        step size. For states from outside (a deserialized FMU state)."""
        n_steps, y, ist, snap, poly = state[5], state[6], state[8], state[10], state[11]
        x_e = self.model.kin.x_e
        for name, st_, y_ in (("state", ist, y), ("snapshot", *((None, None) if snap is None else (snap[2], snap[1])))):
            if st_ is None:
                continue
            stuck, hn, stop = st_[I_STUCK], st_[I_HN], st_[I_STOP]
            if not (stuck == int(stuck) and -1 <= stuck < len(self._xc)):
                raise ValueError(f"{name}: stuck index {stuck!r}, expected an integer in [-1, {len(self._xc) - 1}]")
            if not hn > 0:
                raise ValueError(f"{name}: next step size {hn!r}, expected > 0")
            if stop not in (-1.0, 0.0, 1.0):
                raise ValueError(f"{name}: stop flag {stop!r}, expected -1, 0 or 1")
            if not 0.0 <= y_[0] <= x_e:
                raise ValueError(f"{name}: stroke {y_[0]!r} m, expected 0 <= x <= x_e = {x_e:.6g} m")
        if not (n_steps >= 0 and (poly is None or poly[1] > 0)):
            raise ValueError("negative step count, or an interpolation step of zero length")

    def set_state(self, state: tuple) -> None:
        self.t, self.V, self.F, self.ts, self.V_sol, self.n_steps, y, out, ist, ws, self._snap, self._poly = state
        self.y = y.copy()
        self.out = out.copy()
        self._ist[:] = ist
        for a, b in zip(self._ws, ws):
            a[...] = b


INPUT_RTOL = 1e-12     # relative difference of two inputs taken as the same (fmi2_python.c reads it)


def same_input(a: float, b: float) -> bool:
    return abs(a - b) <= INPUT_RTOL * max(abs(a), abs(b))


def _finite_positive(name, v):
    if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: expected a finite number > 0, got {v!r}")
