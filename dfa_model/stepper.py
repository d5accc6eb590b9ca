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

from .equations import R_ANG, R_C, R_FE, R_I, R_LZ, R_U, R_V, R_X
from .integrator import OK, integrate
from .model import DFAModel
from .parameters import Parameters
from .solver import _STATUS, SolverError

# output name -> record column (units: m, m/s, m, rad, N, A, F, J)
OUTPUTS = {"stroke": R_X, "velocity": R_V, "zipped_length": R_LZ, "zipping_angle": R_ANG,
           "electrostatic_force": R_FE, "current": R_I, "capacitance": R_C, "stored_energy": R_U}


class Stepper:
    """Advance an actuator through communication steps.

    stepper = Stepper(params, v_nominal=6000.0)
    stepper.step(1e-3, voltage=6000.0, force=5.0)   # integrate [t, t + 1 ms]
    stepper.outputs["stroke"]

    v_nominal (V) sets the charge scale of the error control (as the protocol amplitude
    does in `simulate`); x0 is the initial stroke (m)."""

    def __init__(self, params: Parameters | DFAModel, *, v_nominal: float = 1000.0, x0: float = 0.0,
                 t0: float = 0.0, rtol: float | None = None, max_steps: int = 1_000_000):
        self.model = params if isinstance(params, DFAModel) else DFAModel(params)
        p = self.model.params
        _finite_positive("v_nominal", v_nominal)
        if not (math.isfinite(x0) and 0.0 <= x0 <= self.model.kin.x_e):
            raise ValueError(f"x0: expected a stroke in [0, {self.model.kin.x_e:g}] m, got {x0!r}")
        self.rtol = p.rtol if rtol is None else float(rtol)
        self.max_steps = int(max_steps)
        self._scale = self.model.scales(v_nominal)
        self._xc = self.model.force_jumps()
        self.n_steps = 0
        self.t = float(t0)
        self.y = self.model.initial_state(x0)
        self.V = 0.0                     # the voltage applied up to t (uncharged start)
        self.F = 0.0
        self._ws, self._ist = self.model.workspace(1e-6)
        row, _ = self.model.diagnostics(self.y, 0.0, 0.0)
        self._row = row
        self._row[R_X] = self.y[0]

    # ------------------------------------------------------------------ stepping
    def step(self, dt: float, voltage: float, force: float = 0.0) -> None:
        """Integrate from t to t + dt with the voltage (V) and the force (N, opposing
        zipping) held constant; a change from the previous inputs is a jump at t."""
        _finite_positive("dt", dt)
        for name, val in (("voltage", voltage), ("force", force)):
            if not math.isfinite(val):
                raise ValueError(f"{name}: expected a finite number, got {val!r}")
        t1 = self.t + dt
        m = self.model
        seg_t = np.array([self.t, t1])
        rec, _, stats, y_end = integrate(
            m.cfg, m.geo, m.mat, m.law.law_id, m.law.params, self.y, seg_t, np.array([float(voltage)]),
            np.zeros(1), np.array([float(force)]), np.zeros(1), self.V, self.rtol, self._scale,
            np.array([t1]), False, False, self.max_steps, self._xc, self._ws, self._ist)
        if int(stats[4]) != OK:
            raise SolverError(f"step: stopped at t = {stats[5]:.9g} s in [{self.t:.9g}, {t1:.9g}] s because "
                              f"{_STATUS[int(stats[4])]}; restore a saved state or reset")
        self.y = y_end
        self.t = t1
        self.V, self.F = float(voltage), float(force)
        self._row = rec[-1]
        self.n_steps += int(stats[0])

    @property
    def outputs(self) -> dict:
        """The outputs at the current time (SI units; see OUTPUTS)."""
        return {k: float(self._row[c]) for k, c in OUTPUTS.items()}

    def output(self, name: str) -> float:
        return float(self._row[OUTPUTS[name]])

    # ------------------------------------------------------------------ state
    def get_state(self) -> tuple:
        """A copy of everything the next step depends on."""
        return (self.t, self.V, self.F, self.n_steps, self.y.copy(), self._row.copy(), self._ist.copy(),
                tuple(a.copy() for a in self._ws))

    def set_state(self, state: tuple) -> None:
        t, V, F, n_steps, y, row, ist, ws = state
        self.t, self.V, self.F, self.n_steps = t, V, F, n_steps
        self.y = y.copy()
        self._row = row.copy()
        self._ist[:] = ist
        for a, b in zip(self._ws, ws):
            a[...] = b


def _finite_positive(name, v):
    if not (isinstance(v, (int, float, np.floating)) and math.isfinite(v) and v > 0):
        raise ValueError(f"{name}: expected a finite number > 0, got {v!r}")
