"""Cycle-averaged surrogate for long polarity-inversion horizons.

A full-duty inversion drive (dfa_model.Bipolar, duty 1: `drive`) holds +V for a share
`positive_share` of each period and -V for the rest, with linear ramps of duration
`t_ramp` through zero at each inversion (t_ramp = 2 V / slew rate, or 2 V C / I_limit with
a current-limited source: the larger).
Over horizons of minutes at tens of Hz, stepping through every inversion costs
thousands of input segments; the averaged form integrates the slow dynamics instead:

    charge   dq_z/dt = a(x) q_z + b(x) V is linear in V, so the period mean <V> drives the
             period-mean charge exactly (a, b do not change over a period's ripple of x);
    force    F_e = c0(x) V^2 + c1(x) V q + c2(x) q^2 is quadratic in V: the period mean
             <V^2> enters the c0 term. With q = <q> + q', q' = b (g - <g>), g = int (V - <V>),
             <V q'> = 0 exactly (periodicity: int g dg = 0), so the c1 term is exact too;
             only c2 <q'^2> is dropped: O((T / tau)^2) smaller than the charge itself.

The kernel's averaged mode (Surrogate.simulate(..., averaged=[<V^2>])) integrates this
with the protocol's segment voltage = <V>: ONE DC segment spans the whole horizon.

Assumption: the charge barely changes over one period, i.e. f >> 1/tau with tau the
interface-charge time constant (about 75 s for vshape-table1: -1/a). The stroke itself
follows the force within the mechanical time b / k_eff (about 2 ms there), so it does
ripple within a period: that ripple is not in the averaged run. It is recovered by
simulating the last few periods of the real (ramped) waveform from the averaged
end state, with the charge's periodic oscillation q' restored at the start phase.

Definitions (one implementation, dfa_model.metrics.last_periods, used for the surrogate
and the full model alike; README, 'Words with one meaning'):

    ripple  peak-to-peak stroke over the last whole period of the horizon (m)
    drift   x_static - x_mean_end (m): x_static = dfa_model.physics.statics.equilibrium_stroke
            (params, V, F), the uncharged static stroke; x_mean_end the time mean of the
            stroke over that last period. Both the slow charge drift (low f, or
            positive_share != 0.5) and the sag at the zero crossings (high f, finite slew)
            count. Positive when stroke is lost; negative: the stroke ends above the
            static stroke.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from dfa_model import metrics
from dfa_model.waveforms import Bipolar, Protocol, Stage, charge_phase_offset


N_TAIL = 4   # periods of the real waveform simulated after the averaged run


def max_frequency(positive_share: float, t_ramp: float) -> float:
    """Highest frequency at which the full-duty inversion still reaches +-V: both ramps
    must fit in each polarity's share (t_ramp <= min(positive_share, 1 - positive_share)
    / f). inf without ramps."""
    return math.inf if t_ramp <= 0 else min(positive_share, 1.0 - positive_share) / t_ramp


def ramp_time(V, slew_rate=None, current_limit=None, capacitance=None) -> float:
    """Duration (s) of one inversion from +V to -V: 2 V / slew_rate, or 2 V C /
    current_limit with a current-limited source; the larger of those given (0: ideal)."""
    t = 0.0
    if slew_rate is not None:
        t = max(t, 2.0 * abs(V) / slew_rate)
    if current_limit is not None:
        if capacitance is None:
            raise ValueError("capacitance: required with current_limit (F)")
        t = max(t, 2.0 * abs(V) * capacitance / current_limit)
    return t


def averaged_inputs(V, f, positive_share=0.5, t_ramp=0.0):
    """(<V>, <V^2>) over one period of full-duty inversion with ramps of t_ramp centred on
    the ideal switching instants: the ramps are antisymmetric about them, so <V> =
    (2 positive_share - 1) V exactly; a ramp's mean square is V^2 / 3, so <V^2> =
    V^2 (1 - 2 t_ramp f) + V^2 (2 t_ramp f) / 3 = V^2 (1 - 4/3 t_ramp f)."""
    V, f, share, t_ramp = float(V), float(f), float(positive_share), float(t_ramp)
    if not (f > 0):
        raise ValueError(f"f: got {f!r}, expected a value > 0 Hz")
    if not (0 < share < 1):
        raise ValueError(f"positive_share: got {share!r}, expected a value in (0, 1)")
    if t_ramp < 0:
        raise ValueError(f"t_ramp: got {t_ramp!r}, expected a value >= 0 s")
    if f > max_frequency(share, t_ramp) * (1 + 1e-12):
        raise ValueError(f"f: got {f:g} Hz, expected <= {max_frequency(share, t_ramp):g} Hz (the ramps of "
                         f"{t_ramp:g} s must fit in each polarity's share of the period)")
    return (2.0 * share - 1.0) * V, V * V * (1.0 - 4.0 / 3.0 * t_ramp * f)


def last_period(result, period: float, t_end: float | None = None):
    """(ripple, mean) of the stroke over the last whole period ending at t_end (default the
    end of the record): dfa_model.metrics.last_periods on any result with a StrokeTrace."""
    return metrics.last_periods(result.trace, period, 1, t_end)


def whole_periods(horizon: float, f: float) -> float:
    """The longest run of whole periods within the horizon (s): what the design verifies
    and writes out, so that its last period ends the run."""
    T = 1.0 / f
    n = math.floor(horizon / T + 1e-9)
    if n < 1:
        raise ValueError(f"horizon: {horizon:g} s is shorter than one period ({T:g} s) at {f:g} Hz")
    return n * T


@dataclass
class AveragedResult:
    """The averaged run (`slow`: the period-mean stroke and charges over the horizon,
    a SurrogateResult with t, x, q_z, q_d), the real-waveform tail (`tail`, the last
    N_TAIL periods, time shifted to end at the horizon), and the metrics."""

    slow: object
    tail: object
    frequency: float
    positive_share: float
    t_ramp: float
    V_mean: float
    W_mean: float
    x_static: float
    ripple: float
    x_mean_end: float
    wall_time: float

    @property
    def drift(self) -> float:
        return self.x_static - self.x_mean_end

    @property
    def t(self):
        return self.slow.t

    @property
    def x(self):
        return self.slow.x

    def summary(self) -> dict:
        return {"frequency": self.frequency, "positive_share": self.positive_share, "t_ramp": self.t_ramp,
                "ripple": self.ripple,
                "drift": self.drift, "x_mean_end": self.x_mean_end, "x_static": self.x_static,
                "wall_time": self.wall_time}


def static_stroke(params, V, F) -> float:
    """x_static of the drift's definition (uncharged static stroke, full model's maps)."""
    import warnings

    from dfa_model.physics.dielectrics import PhysicsWarning
    from dfa_model.physics.statics import equilibrium_stroke
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicsWarning)
        return float(equilibrium_stroke(params, V, F))


def drive(V, f, positive_share=0.5, t_ramp=0.0, balanced=True) -> Bipolar:
    """Full-duty inversion (dfa_model.Bipolar, duty 1) with ramps of t_ramp per inversion
    (slew rate 2 |V| / t_ramp), started at the charge-balanced phase unless
    balanced=False: the drive the design scans, verifies and writes out."""
    slew = 2.0 * abs(V) / t_ramp if t_ramp > 0 else None
    return Bipolar(V, f, 1.0, slew_rate=slew, phase="balanced" if balanced else 0.0, positive_share=positive_share)


def simulate_averaged(s, V, F, f, positive_share, horizon, t_ramp=0.0, *, balanced=True, x_static=None, rtol=1e-4,
                      tail_rtol=1e-6, n_tail=N_TAIL) -> AveragedResult:
    """Period-mean stroke of surrogate `s` under full-duty inversion (`drive`: V, f,
    positive_share, t_ramp)
    against load F over `horizon` s, from uncharged at rest: one averaged kernel run
    (a DC protocol of <V> with averaged=[<V^2>]), then `n_tail` periods of the real
    waveform from its end state for the ripple and the end's period mean (module
    docstring: definitions and assumption). The tail's periods replace the horizon's
    last `n_tail` periods when the horizon is longer than that, so the total simulated
    time is the horizon; shorter horizons run the real waveform throughout."""
    t0 = time.perf_counter()
    V_mean, W = averaged_inputs(V, f, positive_share, t_ramp)
    wave = drive(V, f, positive_share, t_ramp, balanced)
    T = 1.0 / f
    if x_static is None:
        x_static = static_stroke(s.params, V, F)
    span = whole_periods(horizon, f)
    t_slow = horizon - n_tail * T
    if t_slow <= 0.0:
        # short horizon: the real waveform all the way (whole periods ending at the horizon)
        slow = None
        tail = s.simulate(Protocol([Stage(wave, span, "hold")]), F, rtol=tail_rtol)
        t_shift = horizon - span
    else:
        # the charge is q = <q> + b (g - <g>) (module docstring), b each charge state's input
        # gain: an uncharged start at phase 0 (g = 0) has the period-mean charge <q>(0) = b <g>,
        # and the tail, starting at the drive's phase again, q = <q>(end) - b <g>. The offset
        # b <g> ~ b V T / 4 decays only with tau: on horizons ~ tau it is part of the answer.
        g0 = charge_phase_offset(wave)
        gains = s.input_gains(min(max(x_static, 0.0), s.x_e))
        y_start = {name: b * g0 for name, b in gains.items()}
        slow = s.simulate(Protocol.dc(V_mean, t_slow), F, rtol=rtol, averaged=[W], y0=y_start)
        y = slow.y_end.copy()
        gains = s.input_gains(min(max(y[0], 0.0), s.x_e))
        names = dict(s._names)
        y0 = {name: y[names[name]] for name in s.state_names}
        for name, b in gains.items():
            y0[name] -= b * g0
        tail = s.simulate(Protocol([Stage(wave, n_tail * T, "hold")]), F, rtol=tail_rtol, y0=y0)
        t_shift = t_slow
    rip, xm = last_period(tail, T)
    res = AveragedResult(slow if slow is not None else tail, tail, f, positive_share, t_ramp, V_mean, W, x_static, rip, xm,
                         time.perf_counter() - t0)
    res.tail_offset = t_shift
    return res


def simulate_full(params, V, F, f, positive_share, horizon, t_ramp=0.0, *, balanced=True, x_static=None,
                  power=False, **kw):
    """The full model over the whole horizon on the same drive (whole periods): (Result,
    ripple, drift) with the module's definitions. power=True also integrates the energy
    record, sampled at the last period's start and the end, so that res.input_power()
    is exact (the Result's arrays then hold those points only)."""
    from dfa_model import simulate
    span = whole_periods(horizon, f)
    if x_static is None:
        x_static = static_stroke(params, V, F)
    if power:
        kw.update(energy=True, t_eval=np.array([0.0, span - 1.0 / f, span]))
    res = simulate(params, Protocol([Stage(drive(V, f, positive_share, t_ramp, balanced), span, "hold")]), load=F,
                   **kw)
    rip, xm = last_period(res, 1.0 / f)
    return res, rip, x_static - xm
