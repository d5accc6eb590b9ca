"""Cycle-averaged surrogate for long polarity-inversion horizons.

A bipolar drive (`BipolarTrapezoid`) holds +V for a share `duty` of each period and -V
for the rest, with linear ramps of duration `t_ramp` through zero at each inversion
(t_ramp = 2 V / slew rate, or 2 V C / I_limit with a current-limited source: the larger).
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
simulating the last few periods of the real (trapezoidal) waveform from the averaged
end state, with the charge's periodic oscillation q' restored at the start phase.

Definitions (one implementation, `last_period`, used for the surrogate and the full
model alike):

    ripple  peak-to-peak stroke over the last whole period of the horizon (m)
    drift   x_static - x_mean_end (m): x_static = dfa_model.statics.equilibrium_stroke
            (params, V, F), the uncharged static stroke; x_mean_end the time mean of the
            stroke over that last period. Both the slow charge drift (low f, or duty != 0.5)
            and the sag at the zero crossings (high f, finite slew) count. Negative: the
            stroke ends above the static stroke.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from dfa_model import metrics
from dfa_model.limits import check_segments
from dfa_model.waveforms import (
    Piecewise,
    Protocol,
    Stage,
    Waveform,
    WaveformError,
    _finite,
    _level,
)

from . import kernel

N_TAIL = 4   # periods of the real waveform simulated after the averaged run


def max_frequency(duty: float, t_ramp: float) -> float:
    """Highest frequency at which the trapezoid still reaches +-V: both ramps must fit
    in their half (t_ramp <= min(duty, 1 - duty) / f). inf without ramps."""
    return math.inf if t_ramp <= 0 else min(duty, 1.0 - duty) / t_ramp


@dataclass
class BipolarTrapezoid(Waveform):
    """+V for `duty` of each period, -V for the rest, linear ramps of `t_ramp` s through
    zero centred on the ideal switching instants. Each period starts at 0 V ramping up:
    [0, t_r/2) 0 -> V, +V, [dT - t_r/2, dT + t_r/2) V -> -V, -V, [T - t_r/2, T) -V -> 0.
    With t_ramp = 0: +V on [0, dT), -V on [dT, T). (dfa_model.Bipolar's duty is the share
    of each half period that is on, with 0 V gaps: a different waveform.)

    `phase` (share of a period, in [0, 1)) starts the drive that far into the period.
    BipolarTrapezoid.balanced(...) picks the charge-balanced phase (balanced_phase): the
    interface charge then oscillates about its mean from the first period on, instead of
    about an offset b <g> that only leakage removes (tens of seconds)."""

    V: float
    frequency: float
    duty: float = 0.5
    t_ramp: float = 0.0
    phase: float = 0.0

    def __post_init__(self):
        self.V = _level("voltage", self.V)
        self.frequency = _finite("frequency", self.frequency, 0.0, lo_incl=False, hi=1e6)
        self.duty = _finite("duty", self.duty, 0.0, lo_incl=False, hi=1.0)
        self.t_ramp = _finite("t_ramp", self.t_ramp, 0.0)
        self.phase = _finite("phase", self.phase, 0.0, hi=1.0)
        if self.phase >= 1.0:
            raise WaveformError(f"phase: got {self.phase:g}, expected a value in [0, 1)")
        if self.frequency > max_frequency(self.duty, self.t_ramp) * (1 + 1e-12):
            raise WaveformError(f"frequency: got {self.frequency:g} Hz, expected <= "
                                f"{max_frequency(self.duty, self.t_ramp):g} Hz (ramps of {self.t_ramp:g} s must fit "
                                f"in each polarity's share of the period)")

    def period_pieces(self):
        """(durations, start values, slopes) of one period's linear pieces."""
        T, d, tr, V = 1.0 / self.frequency, self.duty, self.t_ramp, self.V
        h = 0.5 * tr
        s = 2.0 * V / tr if tr > 0 else 0.0
        pieces = [(h, 0.0, s), (d * T - tr, V, 0.0), (tr, V, -s), ((1 - d) * T - tr, -V, 0.0), (h, -V, s)]
        return [(dur, v, sl) for dur, v, sl in pieces if dur > 1e-15 * T]

    @classmethod
    def balanced(cls, V, frequency, duty=0.5, t_ramp=0.0):
        """The drive started at the charge-balanced phase (balanced_phase)."""
        w = cls(V, frequency, duty, t_ramp)
        w.phase = balanced_phase(w)
        return w

    def piecewise(self, duration):
        T = 1.0 / self.frequency
        pieces = self.period_pieces()
        t0 = self.phase * T
        duration_in = duration
        duration = duration + t0      # build from the period's start, cut t0 off below
        n_per = max(math.ceil(duration / T - 1e-9), 1)
        check_segments("frequency", n_per * len(pieces),
                       f"{self.frequency:g} Hz over {duration:g} s; lower the frequency or shorten the run")
        dur = np.array([p[0] for p in pieces])
        acc = np.concatenate([[0.0], np.cumsum(dur)[:-1]])
        k = np.arange(n_per)[:, None]
        t = (k * T + acc[None, :]).ravel()
        v = np.tile([p[1] for p in pieces], n_per)
        sl = np.tile([p[2] for p in pieces], n_per)
        keep = t < duration - 1e-12 * max(duration, 1.0)
        keep[0] = True
        t, v, sl = t[keep], v[keep], sl[keep].astype(float)
        if t0 > 0.0:
            i = max(int(np.searchsorted(t, t0, side="right")) - 1, 0)   # the piece holding t0
            t, v, sl = t[i:] - t0, v[i:].astype(float), sl[i:]
            v[0] += sl[0] * (-t[0])
            t[0] = 0.0
        return Piecewise(np.concatenate([t, [duration_in]]), v.astype(float), sl)


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


def averaged_inputs(V, f, duty, t_ramp=0.0):
    """(<V>, <V^2>) over one period of the bipolar trapezoid: the ramps are antisymmetric
    about the ideal switching instants, so <V> = (2 duty - 1) V exactly; a ramp's mean
    square is V^2 / 3, so <V^2> = V^2 (1 - 2 t_ramp f) + V^2 (2 t_ramp f) / 3
    = V^2 (1 - 4/3 t_ramp f)."""
    V, f, duty, t_ramp = float(V), float(f), float(duty), float(t_ramp)
    if not (f > 0):
        raise ValueError(f"f: got {f!r}, expected a value > 0 Hz")
    if not (0 < duty < 1):
        raise ValueError(f"duty: got {duty!r}, expected a value in (0, 1)")
    if t_ramp < 0:
        raise ValueError(f"t_ramp: got {t_ramp!r}, expected a value >= 0 s")
    if f > max_frequency(duty, t_ramp) * (1 + 1e-12):
        raise ValueError(f"f: got {f:g} Hz, expected <= {max_frequency(duty, t_ramp):g} Hz (the ramps of "
                         f"{t_ramp:g} s must fit in each polarity's share of the period)")
    return (2.0 * duty - 1.0) * V, V * V * (1.0 - 4.0 / 3.0 * t_ramp * f)


def _charge_profile(wave: BipolarTrapezoid, n: int = 4001):
    """(t, g, <g>) over one period from the drive's start: g(t) = int_0^t (V - <V>) dt'
    (V s), trapezoid rule on n points, and its period mean."""
    T = 1.0 / wave.frequency
    t = np.linspace(0.0, T, n)
    v = wave.piecewise(T)(t) - (2 * wave.duty - 1) * wave.V
    g = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t))])
    return t, g, float(np.sum(0.5 * (g[1:] + g[:-1]) * np.diff(t)) / T)


def balanced_phase(wave: BipolarTrapezoid, n: int = 4001) -> float:
    """The phase (share of a period) at which g(t) = int_0^t (V - <V>) dt' passes its
    period mean while rising: a drive started there has charge_phase_offset 0. For duty
    0.5 and ideal switching that is T/4: half a pulse first."""
    t, g, gm = _charge_profile(BipolarTrapezoid(wave.V, wave.frequency, wave.duty, wave.t_ramp), n)
    sg = 1.0 if wave.V > 0 else -1.0
    i_peak = int(np.argmax(sg * g))
    # g runs monotonically from 0 to its extreme over the first polarity: interpolate
    return float(np.interp(sg * gm, sg * g[:i_peak + 1], t[:i_peak + 1]) / t[-1])     # t[-1] = T


def charge_phase_offset(wave: BipolarTrapezoid, n: int = 4001) -> float:
    """<g> - g(0) with g(t) = int_0^t (V - <V>) dt' over one period (V s): the periodic
    charge oscillation is q' = b (g - <g>), so a run starting at phase 0 starts at
    q = <q> - b (<g> - g(0)) = <q> - b <g>."""
    return _charge_profile(wave, n)[2]


def last_period(result, period: float, t_end: float | None = None):
    """(ripple, mean) of the stroke over the last whole period ending at t_end (default
    the end of the record): peak-to-peak and time mean (m). Works on any result with a
    StrokeTrace (the full model's Result, a SurrogateResult)."""
    tr = result.trace
    t1 = tr.t1 if t_end is None else t_end
    c = metrics.cycles(tr, period, t1 - period, t1)
    if len(c) == 0:
        raise ValueError(f"period: {period:g} s is longer than the record ({tr.t1 - tr.t0:g} s)")
    return float(c[-1, 3] - c[-1, 2]), float(c[-1, 1])


@dataclass
class AveragedResult:
    """The averaged run (`slow`: the period-mean stroke and charges over the horizon,
    a SurrogateResult with t, x, q_z, q_d), the real-waveform tail (`tail`, the last
    N_TAIL periods, time shifted to end at the horizon), and the metrics."""

    slow: object
    tail: object
    frequency: float
    duty: float
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
        return {"frequency": self.frequency, "duty": self.duty, "t_ramp": self.t_ramp, "ripple": self.ripple,
                "drift": self.drift, "x_mean_end": self.x_mean_end, "x_static": self.x_static,
                "wall_time": self.wall_time}


def static_stroke(params, V, F) -> float:
    """x_static of the drift's definition (uncharged static stroke, full model's maps)."""
    import warnings

    from dfa_model.dielectrics import PhysicsWarning
    from dfa_model.statics import equilibrium_stroke
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PhysicsWarning)
        return float(equilibrium_stroke(params, V, F))


def drive(V, f, duty=0.5, t_ramp=0.0, balanced=True) -> BipolarTrapezoid:
    """The bipolar trapezoid, started at the charge-balanced phase unless balanced=False."""
    return BipolarTrapezoid.balanced(V, f, duty, t_ramp) if balanced else BipolarTrapezoid(V, f, duty, t_ramp)


def simulate_averaged(s, V, F, f, duty, horizon, t_ramp=0.0, *, balanced=True, x_static=None, rtol=1e-4,
                      tail_rtol=1e-6, n_tail=N_TAIL) -> AveragedResult:
    """Period-mean stroke of surrogate `s` under a bipolar trapezoid (V, f, duty, t_ramp)
    against load F over `horizon` s, from uncharged at rest: one averaged kernel run
    (a DC protocol of <V> with averaged=[<V^2>]), then `n_tail` periods of the real
    waveform from its end state for the ripple and the end's period mean (module
    docstring: definitions and assumption). The tail's periods replace the horizon's
    last `n_tail` periods when the horizon is longer than that, so the total simulated
    time is the horizon; shorter horizons run the real waveform throughout."""
    t0 = time.perf_counter()
    V_mean, W = averaged_inputs(V, f, duty, t_ramp)
    wave = drive(V, f, duty, t_ramp, balanced)
    T = 1.0 / f
    if x_static is None:
        x_static = static_stroke(s.params, V, F)
    n_total = math.floor(horizon / T + 1e-9)
    if n_total < 1:
        raise ValueError(f"horizon: {horizon:g} s is shorter than one period ({T:g} s) at {f:g} Hz")
    t_slow = horizon - n_tail * T
    if t_slow <= 0.0:
        # short horizon: the real waveform all the way (whole periods ending at the horizon)
        slow = None
        tail = s.simulate(Protocol([Stage(wave, n_total * T, "hold")]), F, rtol=tail_rtol)
        t_shift = horizon - n_total * T
    else:
        # the charge is q = <q> + b (g - <g>) (module docstring): an uncharged start at
        # phase 0 (g = 0) has the period-mean charge <q>(0) = b <g>, and the tail, starting
        # at phase 0 again, q = <q>(end) - b <g>. The offset b <g> ~ b V T / 4 decays only
        # with tau: on horizons ~ tau it is part of the answer.
        # (the front layer's share of q_d oscillates with its own rate b_f: q_d' = (b - b_f) g')
        row = np.empty(kernel.NTAB)
        kernel._row(s.tables, s.x_e, min(max(x_static, 0.0), s.x_e), row)
        g0 = charge_phase_offset(wave)
        y_start = {"q_z": row[kernel.B_V] * g0}
        if s.has_deficit:
            y_start["q_d"] = (row[kernel.B_V] - row[kernel.B_F]) * g0
        slow = s.simulate(Protocol.dc(V_mean, t_slow), F, rtol=rtol, averaged=[W], y0=y_start)
        y = slow.y_end.copy()
        kernel._row(s.tables, s.x_e, min(max(y[0], 0.0), s.x_e), row)
        y0 = {"x": y[0], "q_z": y[2] - row[kernel.B_V] * g0}
        if s.has_deficit:
            y0["q_d"] = y[3] - (row[kernel.B_V] - row[kernel.B_F]) * g0
        if s.has_mass:
            y0["v"] = y[1]
        tail = s.simulate(Protocol([Stage(wave, n_tail * T, "hold")]), F, rtol=tail_rtol, y0=y0)
        t_shift = t_slow
    rip, xm = last_period(tail, T)
    res = AveragedResult(slow if slow is not None else tail, tail, f, duty, t_ramp, V_mean, W, x_static, rip, xm,
                         time.perf_counter() - t0)
    res.tail_offset = t_shift
    return res


def simulate_full(params, V, F, f, duty, horizon, t_ramp=0.0, *, balanced=True, x_static=None, **kw):
    """The full model over the whole horizon on the same trapezoid (whole periods):
    (Result, ripple, drift) with the module's definitions."""
    from dfa_model import simulate
    T = 1.0 / f
    n_total = math.floor(horizon / T + 1e-9)
    if n_total < 1:
        raise ValueError(f"horizon: {horizon:g} s is shorter than one period ({T:g} s) at {f:g} Hz")
    if x_static is None:
        x_static = static_stroke(params, V, F)
    res = simulate(params, Protocol([Stage(drive(V, f, duty, t_ramp, balanced), n_total * T, "hold")]), load=F,
                   **kw)
    rip, xm = last_period(res, T)
    return res, rip, x_static - xm
