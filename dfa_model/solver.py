"""Run the model through a protocol: `simulate()`."""
from __future__ import annotations

import time
import warnings

import numpy as np

from . import dielectrics
from .dielectrics import PhysicsWarning
from .integrator import MAX_STEPS, NONFINITE, OK, STEP_UNDERFLOW, integrate
from .model import DFAModel
from .parameters import Parameters
from .results import Result
from .waveforms import Load, Protocol, WaveformError, merge

_STATUS = {MAX_STEPS: "the step limit was reached", STEP_UNDERFLOW: "the step size fell below 1e-14 s",
           NONFINITE: "the solution became non-finite"}


class SolverError(RuntimeError):
    """The integration stopped early; `.partial` holds the result up to that time."""

    def __init__(self, msg, partial=None):
        super().__init__(msg)
        self.partial = partial


def _as_model(params_or_model) -> DFAModel:
    if isinstance(params_or_model, DFAModel):
        return params_or_model
    if isinstance(params_or_model, Parameters):
        return DFAModel(params_or_model)
    raise TypeError("simulate: expected Parameters or DFAModel")


def _as_protocol(protocol, duration) -> Protocol:
    if isinstance(protocol, Protocol):
        return protocol
    if isinstance(protocol, (int, float)):
        if duration is None:
            raise WaveformError("duration: required when the protocol is a plain voltage")
        return Protocol.dc(protocol, duration)
    if duration is None:
        raise WaveformError("duration: required when the protocol is a waveform")
    return Protocol.single(protocol, duration)


def simulate(params, protocol, load=0.0, duration=None, *, t_eval=None, energy=False, charges=False,
             rtol=None, x0=0.0, V_before=0.0, y0=None, max_steps=5_000_000, warn=True) -> Result:
    """Simulate an actuator.

    params    Parameters or DFAModel.
    protocol  Protocol, a Waveform (with `duration`), or a DC voltage (with `duration`).
    load      Load, or a constant force in N (opposing zipping).
    t_eval    output times (s); default: every accepted integrator step.
    energy    also integrate the energy balance terms (see Result.energy_balance()).
    charges   also keep the element states at every output (the charge distribution).
    y0        initial state (default: uncharged at rest at x0); V_before the voltage
              just before t = 0 (a jump at t = 0 is booked as an instantaneous charge).
    """
    model = _as_model(params)
    protocol = _as_protocol(protocol, duration)
    if not isinstance(load, Load):
        load = Load(load)
    p = model.params
    T = protocol.duration
    t, V0, Vs, F0, Fs = merge(protocol.piecewise(), load.piecewise(T))
    mat = model.with_k(load.k_load)
    y = model.initial_state(x0) if y0 is None else np.array(y0, dtype=float)
    if y.shape != (model.n,) or not np.all(np.isfinite(y)):
        raise ValueError(f"y0: expected {model.n} finite values")
    t_out = np.empty(0) if t_eval is None else np.asarray(t_eval, float)
    if t_out.size:
        if np.any(np.diff(t_out) < 0) or t_out[0] < 0 or t_out[-1] > T * (1 + 1e-12):
            raise ValueError(f"t_eval: expected increasing times within [0, {T:g}] s")
    rtol = p.rtol if rtol is None else float(rtol)
    scale = model.scales(protocol.amplitude)
    h0 = min(1e-6, T / 100)
    xc = model.force_jumps()
    wall = time.perf_counter()
    ws, ist = model.workspace(h0)
    rec, states, stats, y_end = integrate(model.cfg, model.geo, mat, model.law.law_id, model.law.params, y,
                                          t, V0, Vs, F0, Fs, float(V_before), rtol, scale, t_out,
                                          bool(energy), bool(charges), int(max_steps), xc, ws, ist, False)
    wall = time.perf_counter() - wall
    result = Result(model, protocol, load, rec, states if charges else None, stats, wall, y_end, energy=energy,
                    y0=y, V_before=float(V_before))
    status = int(stats[4])
    if status != OK:
        raise SolverError(f"simulate: stopped at t = {stats[5]:.6g} s of {T:g} s because {_STATUS[status]}; "
                          f"the partial result is attached as .partial", result)
    if warn:
        _physics_warnings(model, result, load)
    return result


def _physics_warnings(model, result, load):
    dielectrics.warn_if_clipped(model.law, float(np.max(result.E_max)) if result.t.size else 0.0)
    x = result.x
    if x.size < 2:
        return
    x_e = model.kin.x_e
    on = np.abs(result.V) > 0
    if np.any(on) and np.max(x[on]) < 1e-3 * x_e:
        warnings.warn("the actuator did not zip: the electrostatic force at x = 0 never exceeded the load "
                      "(voltage too low or force too high)", PhysicsWarning, stacklevel=3)
    elif np.any(on):
        peak = np.max(x)
        if peak > 1e-3 * x_e and x[-1] < 1e-3 * x_e and abs(result.V[-1]) > 0:
            warnings.warn("the actuator fully unzipped under voltage (the load exceeded the decaying "
                          "electrostatic force)", PhysicsWarning, stacklevel=3)
    if np.max(x) >= x_e * (1 - 1e-6):
        warnings.warn("the zipping front reached the electrode end (l_z = l_e)", PhysicsWarning, stacklevel=3)
