"""Run the model through a protocol: `simulate()`."""
from __future__ import annotations

import math
import time
import warnings

import numpy as np

from ..physics import dielectrics
from .. import interrupt, limits
from .._jit import prepare
from ..physics.dielectrics import PhysicsWarning
from ..physics.equations import K, NREC
from .integrator import INTERRUPTED, MAX_STEPS, NONFINITE, OK, OUTPUT_FULL, STEP_UNDERFLOW, integrate
from ..physics.model import DFAModel
from ..io.parameters import ParameterError, Parameters, check_value
from ..io.results import Result
from ..waveforms import Load, Protocol, WaveformError, segments

_STATUS = {MAX_STEPS: "the step limit was reached", STEP_UNDERFLOW: "the step size fell below 1e-14 s",
           NONFINITE: "the solution became non-finite", OUTPUT_FULL: "the output reached its memory limit"}


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


def protocol_load(protocol: Protocol, load) -> Load:
    """The load of a run: `load` (a Load or a constant force, N) if given, else the
    protocol's own (a protocol file's [load]), else 0 N."""
    if load is None:
        load = protocol.load if protocol.load is not None else 0.0
    return load if isinstance(load, Load) else Load(load)


def simulate(params, protocol, load=None, duration=None, *, t_eval=None, energy=False, charges=False,
             rtol=None, x0=0.0, V_before=0.0, y0=None, max_steps=limits.MAX_STEPS, warn=True) -> Result:
    """Simulate an actuator.

    params    Parameters or DFAModel.
    protocol  Protocol, a Waveform (with `duration`), or a DC voltage (with `duration`).
    load      Load, or a constant force in N (opposing zipping); default the protocol's
              own load (a protocol file's [load]), else 0.
    t_eval    output times (s); default: every accepted integrator step.
    energy    also integrate the energy balance terms (see Result.energy_balance()).
    charges   also keep the element states at every output (the charge distribution).
    y0        initial state (default: uncharged at rest at x0); V_before the voltage
              just before t = 0 (a jump at t = 0 is booked as an instantaneous charge).
    max_steps the step limit (accepted and rejected steps): the run stops there with
              SolverError and its partial result.

    Everything is checked before the run (limits.py): the inputs' ranges, the output's
    memory, and that the stroke's motion is slow enough to resolve.
    """
    model = _as_model(params)
    protocol = _as_protocol(protocol, duration)
    load = protocol_load(protocol, load)
    p = model.params
    T = protocol.duration
    t, V0, Vs, F0, Fs = segments(protocol, load)
    mat = model.with_k(load.k_load)
    V_before = limits.finite_within("V_before", V_before, limits.MAX_VOLTAGE)
    y = _initial(model, x0, y0, V_before)
    max_steps = _count("max_steps", max_steps)
    if len(t) - 1 > max_steps:
        raise limits.LimitError(f"max_steps: the inputs have {len(t) - 1:,} segments (switches, samples), each at "
                                f"least one solver step, above max_steps = {max_steps:,}: raise it (--max-steps) or "
                                f"shorten the run")
    t_out = _output_times(t_eval, T, model.n if charges else 0)
    rtol = p.rtol if rtol is None else _rtol(rtol)
    check_mechanics(model, mat[K], np.max(np.abs(np.concatenate([V0, V0 + Vs * np.diff(t)]))),
                    np.max(np.abs(np.concatenate([F0, F0 + Fs * np.diff(t)]))))
    scale = model.scales(protocol.amplitude, energy)
    h0 = min(1e-6, T / 100)
    xc = model.force_jumps()
    while True:
        ws, ist = model.workspace(h0)
        args = (model.cfg, model.geo, mat, model.law.law_id, model.law.params, y, t, V0, Vs, F0, Fs, float(V_before),
                rtol, scale, t_out, bool(energy), bool(charges), max_steps, xc, ws, ist, False, True,
                _max_rows(model.n if charges else 0), interrupt.FLAG)
        prepare(integrate, *args)     # numba's compilation or cache load (if not compiled ahead): not the run's time
        # Ctrl-C stops the kernel within a step and raises KeyboardInterrupt here (interrupt.py)
        with interrupt.KERNEL:
            started = time.perf_counter()
            rec, states, stats, y_end, trace = integrate(*args)
            wall = time.perf_counter() - started
        if int(stats[4]) != INTERRUPTED:
            break
        if not interrupt.rerun():     # another signal's wakeup: run again
            raise KeyboardInterrupt
    result = Result(model, protocol, load, rec, states if charges else None, stats, wall, y_end, energy=energy,
                    y0=y, V_before=float(V_before), trace=trace)
    result.started = started      # time.perf_counter() when the run began (dfa simulate's startup_time)
    status = int(stats[4])
    if status != OK:
        raise SolverError(f"simulate: stopped at t = {stats[5]:.6g} s of {T:g} s because {_STATUS[status]}"
                          f"{_hint(status, model, max_steps)}; the partial result is attached as .partial", result)
    if warn:
        _physics_warnings(model, result, load)
    return result


def _hint(status, model, max_steps):
    """What to change after a failed run."""
    p = model.params
    if status == MAX_STEPS:
        text = f" ({max_steps:,} steps): raise max_steps (--max-steps), shorten the run"
        if p.m > 0:
            text += f", or damp the mechanics (m = {p.m:g} kg, b = {p.b:g} N s/m: a light, weakly damped mass rings fast)"
        return text
    if status == OUTPUT_FULL:
        return (f" ({limits.MAX_OUTPUT_SAMPLES:,} samples or {limits.MAX_OUTPUT_BYTES / 2 ** 30:g} GiB): sample the "
                f"output (t_eval, --dt) or shorten the run")
    return f": check rtol = {p.rtol:g}, the resistivity law and the inputs (a smaller rtol can help)"


def _count(name, value):
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{name}: got {value!r}, expected an integer >= 1")
    return int(value)


def _rtol(value):
    check_value("rtol", value)
    return float(value)


def _initial(model, x0, y0, V_before=0.0):
    """The initial state: uncharged at rest at x0, or y0 (checked)."""
    x_e = model.kin.x_e
    if y0 is None:
        x0 = limits.finite_within("x0", x0, math.inf)
        if not 0.0 <= x0 <= x_e:
            raise ValueError(f"x0: got {x0:g} m, expected a stroke with 0 <= x0 <= x_e = {x_e:.6g} m")
        return model.initial_state(x0, V_before)
    y = np.array(y0, dtype=float)
    if y.shape != (model.n,) or not np.all(np.isfinite(y)):
        raise ValueError(f"y0: expected {model.n} finite values (got shape {y.shape})")
    if not 0.0 <= y[0] <= x_e:
        raise ValueError(f"y0: stroke y0[0] = {y[0]:g} m, expected 0 <= y0[0] <= x_e = {x_e:.6g} m")
    return y


def _max_rows(extra_columns):
    return min(limits.MAX_OUTPUT_SAMPLES, int(limits.MAX_OUTPUT_BYTES // (8 * (NREC + extra_columns))))


def _output_times(t_eval, T, extra_columns):
    """t_eval as an array, checked (order, span, memory) before anything runs."""
    if t_eval is None:
        return np.empty(0)
    t_out = np.asarray(t_eval, float).ravel()
    limits.check_rows("t_eval", t_out.size, NREC + extra_columns, "sample more coarsely or shorten the run")
    if t_out.size and (not np.all(np.isfinite(t_out)) or np.any(np.diff(t_out) < 0) or t_out[0] < 0
                       or t_out[-1] > T * (1 + 1e-12)):
        raise ValueError(f"t_eval: expected finite non-decreasing times within [0, {T:g}] s")
    return t_out


def zip_force_per_volt2(model) -> float:
    """Static zipping force at x = 0 per V^2 (uncharged: the force is exactly ~ V^2)."""
    from ..physics.statics import static_state
    return abs(model.electrostatic_force(static_state(model, 0.0, 1.0), 1.0))


def check_mechanics(model, k_total, V_max, F_max, c_zip=None):
    """Refuse mechanics too fast to integrate: the stroke must take at least
    limits.TAU_MECH_MIN to cross its range under the largest force (static zipping force
    at V_max, load F_max, spring k_total x_e). c_zip: zip_force_per_volt2, if known."""
    p = model.params
    x_e = model.kin.x_e
    F_zip = (zip_force_per_volt2(model) if c_zip is None else c_zip) * V_max * V_max
    F_s = max(F_zip, abs(F_max), k_total * x_e)
    if F_s <= 0.0:
        return
    tau = max(p.b * x_e / F_s, math.sqrt(p.m * x_e / F_s))
    if tau < limits.TAU_MECH_MIN:
        raise ParameterError(
            f"b: {p.b:g} N s/m (m = {p.m:g} kg) against a force of {F_s:.3g} N (zipping force at {V_max:g} V, "
            f"load {F_max:g} N, spring {k_total * x_e:.3g} N) moves the stroke across its range in {tau:.2g} s, "
            f"faster than the solver resolves ({limits.TAU_MECH_MIN:g} s): raise b or m, or lower the voltage or load")


def _physics_warnings(model, result, load):
    """Warnings on what the run did, stated from the solver's record (the trace for the
    stroke, so no sampling hides a peak)."""
    dielectrics.warn_if_clipped(model.law, float(np.max(result.E_max)) if result.t.size else 0.0)
    x_e = model.kin.x_e
    on = np.abs(result.V) > 0
    if not np.any(on):
        return
    peak = result.peak_stroke
    if peak < 1e-3 * x_e:
        # at rest near x = 0, the load there is F (the spring adds k x ~ 0)
        margin = float(np.max(result.Fe[on] - result.F[on]))
        if margin <= 0:
            warnings.warn(f"the actuator did not zip: the electrostatic force at x = 0 (at most "
                          f"{float(np.max(result.Fe[on])):.3g} N) never exceeded the load (at least "
                          f"{float(np.min(result.F[on])):.3g} N); raise the voltage or lower the load",
                          PhysicsWarning, stacklevel=3)
        else:
            warnings.warn(f"the actuator barely moved: the peak stroke {peak:.3g} m is below 0.1 % of its range "
                          f"x_e = {x_e:.3g} m, although the zipping force exceeded the load by up to {margin:.3g} N "
                          f"(high damping b = {model.params.b:g} N s/m, a stiff spring or a short run)",
                          PhysicsWarning, stacklevel=3)
    elif result.final_stroke < 1e-3 * x_e and abs(result.V[-1]) > 0:
        warnings.warn("the actuator fully unzipped under voltage (the load exceeded the decaying "
                      "electrostatic force)", PhysicsWarning, stacklevel=3)
    if peak >= x_e * (1 - 1e-9):
        warnings.warn(f"the stroke reached its stop at x_e = {x_e:.6g} m: the zipping front is at the electrode "
                      f"end, where the electrostatic force vanishes", PhysicsWarning, stacklevel=3)
