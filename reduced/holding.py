"""Holding a commanded stroke despite charge retention.

Under a constant (DC) voltage the interface charge builds up (tau ~ 75 s for the Table 1
V-shape) and screens the field: the zipping force falls and the stroke decays (6 kV /
5 N: 0.87 mm at first, ~0.4 mm after 20 s, fully unzipped after ~40 s). The scheme here:

    drive   polarity inversion at a fixed frequency f (default 10 Hz, square wave, 100 %
            duty): V(t) = +-A(t), the sign flipping every half period. The interface
            charge then averages out (feedforward charge balancing), and V^2 = A^2 stays
            what the stroke sees.
    loop    a sampled PI controller on the stroke (every dt_control) sets the amplitude A,
            with the open-loop voltage V0 that gives x_ref in the statics as feedforward,
            clamped to [0, V_max] with conditional-integration anti-windup. The integral
            removes what inversion leaves (a ~1 um offset of the mean stroke, the slow
            residual drift) and anything the feedforward did not know (load changes,
            parameter error).

Why inversion + amplitude adaptation and not DC amplitude adaptation (mode="dc", also
implemented): under DC the charge follows the voltage, so holding the force needs a
voltage that keeps climbing, about V0 / tau per second: the surrogate's steady state
keeps only 1.7e-5 of the force at x_ref = 0.8 mm (it would need ~240 x V0). On the full
model (x_ref = 0.8 mm, 5 N) the DC loop's amplitude climbs ~35 V/s, and the stroke breaks
into a growing oscillation around x_ref (+-50 um at 5 s, +-0.5 mm at 40 s), with these
gains or a fifth of them, although the surrogate's linearization at q_z = 0 gives it 89 deg
of phase margin: the charged actuator under DC does not hold a stroke. The amplitude hits
V_max = 10 kV at ~115 s and the actuator unzips (compare_hold(..., include_dc_loop=True)).
Inversion costs the switching charge (2 C A^2 per flip: ~0.55 W at 5.8 kV, 10 Hz) but
holds indefinitely with A ~ V0: on the full model inversion alone at V0 stays within
0.53 um of x_ref over 300 s, and the loop adds the correction of what V0 does not know
(a 5 -> 6 N load step: inversion settles 178 um low, the loop returns within ~1 s).

Tuning (tune_hold_controller, python-control on the surrogate): the quasi-static plant
from amplitude to stroke is the surrogate's linearization at the mechanical balance with
the charge frozen (q_z = 0: inversion keeps it near zero), G(s) = g p / (s + p) (Table 1:
g = 0.36 um/V, p = 482 rad/s). The PI zero cancels the mechanical pole, kp = ki / p, and
ki = w_c / g puts the crossover at w_c, by default the smallest of p / 10, 2 pi f / 10
(an order below the inversion ripple at 2 f) and 0.2 / dt_control. The margins are those
of the sampled loop (ZOH plant, discrete PI) from control.margin.

Simulation: simulate_hold closes the loop on the full model with dfa_model.numerics.stepper.Stepper
(the class the FMU runs: exact=True is the FMU's land_on_communication_points = true),
cosim_hold_fmu closes the same loop around the FMU under fmpy (a Python master). Both set
the stepper's clock to k * dt at step k, as the FMU does, so the two agree to rounding.
"""
from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable

import numpy as np

from dfa_model import DFAModel, limits
from dfa_model.io.parameters import Parameters
from dfa_model.numerics.stepper import OUTPUTS, Stepper

MODES = ("bipolar", "dc")
_I_X, _I_I, _I_C = (list(OUTPUTS).index(n) for n in ("stroke", "current", "capacitance"))


# ---------------------------------------------------------------------- tuning
@dataclasses.dataclass(frozen=True)
class HoldController:
    """A tuned stroke-holding PI loop (amplitude adaptation).

    kp (V/m), ki (V/(m s))     PI gains on the stroke error x_ref - x
    v_ff (V)                   feedforward amplitude: the voltage that gives x_ref in the
                               surrogate's statics (uncharged)
    v_max (V)                  amplitude clamp [0, v_max]
    dt (s)                     sample period the margins are for
    mode, frequency (Hz)       'bipolar': V = +-A flipping every 1/(2 f); 'dc': V = A
    x_ref (m), F (N)           the operating point tuned for
    plant_gain (m/V), plant_pole (rad/s)   quasi-static dx/dV and the mechanical pole
    crossover (rad/s)          design crossover
    gain_margin, phase_margin (deg), gain_crossover, phase_crossover (rad/s): the sampled
                               loop's margins (control.margin; gain_margin inf if none)
    """
    kp: float
    ki: float
    v_ff: float
    v_max: float
    dt: float
    mode: str
    frequency: float
    x_ref: float
    F: float
    plant_gain: float
    plant_pole: float
    crossover: float
    gain_margin: float
    phase_margin: float
    gain_crossover: float
    phase_crossover: float

    def law(self, x_ref=None) -> _PI:
        return _PI(self, self.x_ref if x_ref is None else x_ref)

    def system(self, x_ref=None, name="pi"):
        """This loop's controller as a discrete python-control system of step dt: input
        `stroke` (m), output `voltage` (V), state `integral` (V): the law of law() with the
        polarity simulate_hold applies (+A first, flipped every half period in 'bipolar').
        Closed with control.interconnect around Surrogate.system(dt=dt) it is the
        compiled loop (simulate_hold_surrogate)."""
        import control
        x_ref = self.x_ref if x_ref is None else float(x_ref)
        half = _polarity(self.mode, self.frequency, self.dt)

        def upd(t, z, u, params):
            return [_pi_step(self, x_ref, z[0], u[0])[1]]

        def out(t, z, u, params):
            A = _pi_step(self, x_ref, z[0], u[0])[0]
            return [A if half == 0 or (int(round(t / self.dt)) // half) % 2 == 0 else -A]

        return control.nlsys(upd, out, inputs=["stroke"], outputs=["voltage"], states=["integral"], dt=self.dt,
                             name=name)

    def loop(self):
        """The sampled open loop L(z) = C(z) G_zoh(z) (control.TransferFunction)."""
        import control
        G = control.tf([self.plant_gain * self.plant_pole], [1.0, self.plant_pole])
        return _pi_tf(self.kp, self.ki, self.dt) * control.c2d(G, self.dt, "zoh")


def _pi_tf(kp, ki, dt):
    import control
    # u_k = kp e_k + sum_j<=k ki dt e_j  ->  C(z) = kp + ki dt z / (z - 1)
    return control.tf([kp + ki * dt, -kp], [1.0, -1.0], dt)


def feedforward_voltage(s_or_params, x_ref, F, v_lo=100.0, v_hi=None):
    """The DC voltage whose static (uncharged) stroke is x_ref under the load F: from the
    surrogate's statics for a Surrogate, from dfa_model.physics.statics for Parameters/DFAModel."""
    from scipy.optimize import brentq
    if hasattr(s_or_params, "equilibrium"):
        def stroke(V):
            return float(s_or_params.equilibrium(V, F)[0])
    else:
        import warnings

        from dfa_model import PhysicsWarning
        from dfa_model.physics.statics import equilibrium_stroke

        def stroke(V):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PhysicsWarning)
                return float(equilibrium_stroke(s_or_params, V, F, warn=False))
    v_hi = v_hi or 50_000.0
    if stroke(v_hi) < x_ref:
        raise ValueError(f"x_ref: {x_ref:g} m is not reachable below {v_hi:g} V under {F:g} N; expected a smaller "
                         f"stroke (or load)")
    x_lo = stroke(v_lo)
    if x_lo > x_ref:        # the load pulls it further already (a negative force), or x_ref is tiny
        raise ValueError(f"x_ref: {x_ref:g} m is below the stroke {x_lo:g} m that {v_lo:g} V already holds under "
                         f"{F:g} N; expected a larger stroke (or load)")
    return float(brentq(lambda V: stroke(V) - x_ref, v_lo, v_hi, xtol=1e-6))


DT_MAX = 0.01      # s: the longest default control step


def control_step(frequency: float, mode: str = "bipolar") -> float:
    """The default control step: the longest dt <= DT_MAX that divides the inversion's
    half period into whole steps (the polarity switches on a step), DT_MAX under DC."""
    if mode == "dc":
        return DT_MAX
    half = 1.0 / (2.0 * frequency)
    return half / max(1, math.ceil(half / DT_MAX - 1e-9))


def tune_hold_controller(s, x_ref: float, F: float, bandwidth: float | None = None, *,
                         dt_control: float | None = None, frequency: float = 10.0, mode: str = "bipolar",
                         v_max: float = 10_000.0) -> HoldController:
    """Tune the amplitude-adaptation PI loop on the surrogate `s` (reduced.build) at the
    stroke x_ref (m) under the load F (N). dt_control: the sample period (default
    control_step(frequency): a whole number of steps per half period). bandwidth: the
    crossover (rad/s), default min(p / 10, 2 pi f / 10, 0.2 / dt_control) with p the
    mechanical pole. See the module docstring; the margins returned are the sampled loop's."""
    import control
    if mode not in MODES:
        raise ValueError(f"mode: got {mode!r}, expected one of {', '.join(MODES)}")
    if not frequency > 0:
        raise ValueError(f"frequency: expected a value > 0 Hz, got {frequency!r}")
    if dt_control is None:
        dt_control = control_step(frequency, mode)
    if not dt_control > 0:
        raise ValueError(f"dt: expected a control step > 0 s, got {dt_control!r}")
    _polarity(mode, frequency, dt_control)      # before tuning: a step that cannot switch is an input error
    v_ff = feedforward_voltage(s, x_ref, F)
    if v_ff > v_max:
        raise ValueError(f"x_ref: {x_ref:g} m needs {v_ff:.0f} V, above v_max = {v_max:g} V; expected a smaller stroke "
                         f"(or load)")
    lin = s.linearize(v_ff, F, freeze_charge=True)
    G = control.ss2tf(lin.A, lin.B[:, :1], lin.C[:1, :], lin.D[:1, :1])
    g = float(np.real(control.dcgain(G)))
    pole = float(np.min(np.abs(np.real(control.poles(G)))))
    if not g > 0:
        raise ValueError(f"x_ref: the plant gain dx/dV at {x_ref:g} m ({v_ff:.0f} V) is {g:g}: no stroke control "
                         f"there; expected a stroke the voltage moves")
    wc = bandwidth if bandwidth is not None else min(pole / 10.0, 2 * math.pi * frequency / 10.0, 0.2 / dt_control)
    ki = wc / g
    kp = ki / pole
    Gd = control.c2d(control.tf([g * pole], [1.0, pole]), dt_control, "zoh")
    if mode == "dc":
        # the loop under DC also sees the charge: the full 2-state linearization
        lin_full = s.linearize(v_ff, F)
        Gd = control.c2d(control.ss(lin_full.A, lin_full.B[:, :1], lin_full.C[:1, :], lin_full.D[:1, :1]),
                         dt_control, "zoh")
    # in state space: a 15-state plant turned into a transfer function loses its poles near z = 1
    L = control.ss(_pi_tf(kp, ki, dt_control)) * control.ss(Gd)
    gm, pm, wcg, wcp = _margins(L, wc / 100.0)
    return HoldController(kp=float(kp), ki=float(ki), v_ff=v_ff, v_max=float(v_max), dt=float(dt_control), mode=mode,
                          frequency=float(frequency), x_ref=float(x_ref), F=float(F), plant_gain=g, plant_pole=pole,
                          crossover=float(wc), gain_margin=float(gm), phase_margin=float(pm),
                          gain_crossover=float(wcp), phase_crossover=float(wcg))


def _margins(L, w_low=math.inf):
    """(gain margin, phase margin in deg, phase crossover, gain crossover in rad/s) of the
    sampled loop L, from its response on (0, pi/dt], Nyquist included, on a log grid from
    min(1e-7 pi/dt, w_low): w_low lies below the crossover the loop was tuned for, which a
    short step's 1e-7 pi/dt would miss (a NaN crossover). control.margin is not used: the
    PI's integrator puts a pole at z = 1, where it reports a spurious phase crossover at
    w = 0 (gain margin ~1e-16 for a stable loop), and it misses the crossover at the
    Nyquist frequency, where a sampled loop's phase often reaches -180 deg."""
    w_n = math.pi / L.dt
    w = np.geomspace(min(w_n * 1e-7, w_low), w_n, 20001)
    resp = np.asarray(L(np.exp(1j * w * L.dt))).ravel()
    mag, ph = np.abs(resp), np.degrees(np.unwrap(np.angle(resp)))
    ph -= 360.0 * round(ph[0] / 360.0 + 0.25)       # the integrator's -90 deg at low frequency
    pm, wgc = math.inf, math.nan
    g = np.nonzero((mag[:-1] >= 1.0) & (mag[1:] < 1.0))[0]
    if g.size:
        k = g[0]
        pm, wgc = 180.0 + float(np.interp(0.0, [-mag[k] + 1, -mag[k + 1] + 1], ph[k:k + 2])), \
            float(np.interp(0.0, [-mag[k] + 1, -mag[k + 1] + 1], w[k:k + 2]))
    gm, wpc = math.inf, math.nan
    # phase at -180 deg (mod 360): every crossing, and the Nyquist end when it lands there
    r = (ph + 180.0) / 360.0
    c = np.nonzero(np.floor(r[:-1]) != np.floor(r[1:]))[0]
    cands = [(1.0 / mag[k], w[k]) for k in c]
    if abs(resp[-1].imag) <= 1e-9 * mag[-1] and resp[-1].real < 0:
        cands.append((1.0 / mag[-1], w_n))
    if cands:
        gm, wpc = min(cands)
    return float(gm), float(pm), float(wpc), float(wgc)


# ---------------------------------------------------------------------- amplitude laws
def _pi_step(c: HoldController, x_ref: float, i: float, x: float) -> tuple[float, float]:
    """One sample of the PI law with feedforward, clamp [0, v_max] and conditional
    integration (the integral frozen while clamped against the error): (amplitude,
    integral after). The compiled loop (surrogate_kernel.pi_loop) runs the same law."""
    e = x_ref - x
    i_new = i + c.ki * c.dt * e
    u = c.v_ff + c.kp * e + i_new
    if u > c.v_max:
        return c.v_max, (i_new if e < 0 else i)
    if u < 0.0:
        return 0.0, (i_new if e > 0 else i)
    return u, i_new


class _PI:
    """Sampled PI with feedforward, clamp [0, v_max] and conditional integration (_pi_step)."""

    def __init__(self, c: HoldController, x_ref: float):
        self.c, self.x_ref, self.i = c, float(x_ref), 0.0

    def __call__(self, x: float) -> float:
        u, self.i = _pi_step(self.c, self.x_ref, self.i, x)
        return u


class _Constant:
    def __init__(self, V):
        self.V = float(V)

    def __call__(self, x):
        return self.V


def _polarity(mode, frequency, dt):
    """Steps per half period (bipolar) or 0 (dc)."""
    if mode == "dc":
        return 0
    half = 1.0 / (2.0 * frequency * dt)
    n = round(half)
    if n < 1 or abs(half - n) > 1e-6 * half:
        raise ValueError(f"frequency: a half period 1/(2 f) = {1 / (2 * frequency):g} s must be a whole number of "
                         f"control steps dt = {dt:g} s")
    return n


def _force_fn(F):
    if callable(F):
        return F
    F = float(F)
    return lambda t: F


# ---------------------------------------------------------------------- results
@dataclasses.dataclass
class HoldResult:
    """A hold run sampled every dt: t[k], stroke x[k] at t[k]; A[k], V[k], F[k] the
    amplitude, voltage and force applied over [t[k], t[k+1]] (the last repeats);
    I[k], C[k] the current and capacitance at t[k]."""
    label: str
    t: np.ndarray
    x: np.ndarray
    A: np.ndarray
    V: np.ndarray
    F: np.ndarray
    I: np.ndarray
    C: np.ndarray
    wall_time: float

    def metrics(self, x_ref: float, t_skip: float = 2.0, t_final: float = 1.0, period: float | None = None) -> dict:
        """Deviation from x_ref after t_skip (m): rms, max |.|, final (mean over the last
        t_final s, which averages the inversion ripple); drift: the stroke lost against
        x_ref (m, positive when lost: x_ref minus the mean stroke over the last `period`,
        the inversion's, else t_final; README, 'Words with one meaning'); mean |V| (V);
        drive power proxy (W): mean V I (conduction, recorded current) plus the charge
        pushed at every voltage jump, C V_new (V_new - V_old) each, over the window."""
        w = self.t >= t_skip - 1e-12
        d = self.x[w] - x_ref
        T = self.t[-1] - self.t[w][0]
        fin = self.t >= self.t[-1] - t_final - 1e-12
        Vw, Iw = self.V[w][:-1], self.I[w][1:]              # V over [t_k, t_k+1], I at t_k+1
        idx = np.nonzero(w)[0]
        jumps = [k for k in idx[1:-1] if self.V[k] != self.V[k - 1]]
        e_jump = sum(self.C[k] * self.V[k] * (self.V[k] - self.V[k - 1]) for k in jumps)
        last = self.t >= self.t[-1] - (period or t_final) - 1e-12
        return {"rms_dev": float(np.sqrt(np.mean(d * d))), "max_dev": float(np.max(np.abs(d))),
                "final_error": float(np.mean(self.x[fin]) - x_ref), "drift": float(x_ref - np.mean(self.x[last][:-1])),
                "mean_abs_V": float(np.mean(np.abs(Vw))),
                "hard_switched_power": float(np.mean(Vw * Iw) + e_jump / T), "wall_time": self.wall_time}


def _samples(duration, dt, mode, frequency):
    """(control steps in the hold, steps per half period or 0): the sampling every loop
    runs on, checked."""
    n = round(duration / dt)
    if n < 1 or abs(n * dt - duration) > 1e-9 * duration:
        raise ValueError(f"duration: expected a positive multiple of dt = {dt:g} s, got {duration!r}")
    # each control step is at least one step of the model (a Python call on the full model)
    limits.check_segments("dt", n, f"{duration:g} s in control steps of {dt:g} s; expected a larger dt or a shorter "
                                   f"duration")
    return n, _polarity(mode, frequency, dt)


def _run_loop(step, read, law, mode, frequency, F, duration, dt, label) -> HoldResult:
    """The master loop shared by the in-process and FMU runs: at t_k read the stroke,
    compute the amplitude, apply +-A (polarity from k) and the force over [t_k, t_k + dt]."""
    n, half = _samples(duration, dt, mode, frequency)
    force = _force_fn(F)
    out = {k: np.empty(n + 1) for k in ("t", "x", "A", "V", "F", "I", "C")}
    wall = time.perf_counter()
    for k in range(n + 1):
        t = k * dt
        x, i, c = read()
        A = law(x)
        V = A if half == 0 or (k // half) % 2 == 0 else -A
        f = force(t)
        for key, val in (("t", t), ("x", x), ("A", A), ("V", V), ("F", f), ("I", i), ("C", c)):
            out[key][k] = val
        if k < n:
            step(t, dt, V, f)
    return HoldResult(label, *(out[k] for k in ("t", "x", "A", "V", "F", "I", "C")),
                      wall_time=time.perf_counter() - wall)


def _law_for(controller, x_ref):
    if isinstance(controller, HoldController):
        return controller.law(x_ref), controller.mode, controller.frequency, controller.dt
    raise TypeError("controller: expected a HoldController (tune_hold_controller)")


# ---------------------------------------------------------------------- full model
def simulate_hold(params_or_model: Parameters | DFAModel, controller: HoldController | float, x_ref: float | None = None,
                  F: float | Callable | None = None, duration: float = 120.0, dt_control: float | None = None, *,
                  mode: str | None = None, frequency: float | None = None, v_nominal: float = 6000.0,
                  exact: bool = True, label: str | None = None) -> HoldResult:
    """Run a hold on the full model (dfa_model Stepper, step by step, from rest uncharged).

    controller  a HoldController (closed loop), or a number: an open-loop amplitude (V)
                with `mode` ('dc' or 'bipolar') and `frequency` (Hz)
    x_ref, F    stroke reference (m; default the controller's) and load (N, or a
                function of t; default the controller's)
    dt_control  sample period (s; default the controller's dt, else 0.01)
    v_nominal, exact   Stepper options (the FMU's v_nominal and land_on_communication_points)"""
    if isinstance(controller, HoldController):
        law, mode_, freq, dt = _law_for(controller, x_ref)
        mode, frequency = mode or mode_, frequency or freq
        F = controller.F if F is None else F
        label = label or f"closed loop ({mode})"
    else:
        law, dt = _Constant(controller), 0.01
        mode, frequency = mode or "dc", frequency or 10.0
        F = 0.0 if F is None else F
        label = label or (f"open-loop DC {controller:.0f} V" if mode == "dc" else
                          f"inversion {frequency:g} Hz {controller:.0f} V")
    if mode not in MODES:
        raise ValueError(f"mode: got {mode!r}, expected one of {', '.join(MODES)}")
    dt = dt_control or dt
    model = params_or_model if isinstance(params_or_model, DFAModel) else DFAModel(params_or_model)
    st = Stepper(model, v_nominal=v_nominal, t_end=duration, exact=exact)

    def step(t, h, V, f):
        st.t = t                       # the master's clock, as the FMU's do_step sets it
        st.step(h, V, f)

    def read():
        o = st.out
        return float(o[_I_X]), float(o[_I_I]), float(o[_I_C])

    return _run_loop(step, read, law, mode, frequency, F, duration, dt, label)


def simulate_hold_surrogate(s, controller: HoldController | float, x_ref: float | None = None, F: float | None = None,
                            duration: float = 120.0, dt_control: float | None = None, *, mode: str | None = None,
                            frequency: float | None = None, rtol: float | None = None,
                            label: str | None = None) -> HoldResult:
    """simulate_hold's loop on the surrogate `s`, all of it compiled (the fast closed-loop
    path: dfa_model.numerics.surrogate_kernel.pi_loop, the same PI law, polarity and sampling as
    simulate_hold, one kernel call for the whole hold). controller: a HoldController, or
    an open-loop amplitude (V) with `mode` and `frequency`. F: a constant load (N); a
    load that varies in time needs simulate_hold's Python loop on the full model."""
    from dfa_model.numerics import surrogate_kernel as sk
    from .surrogate import RTOL, SurrogateError
    if isinstance(controller, HoldController):
        c = controller
        x_ref = c.x_ref if x_ref is None else float(x_ref)
        F = c.F if F is None else F
        mode, frequency = mode or c.mode, frequency or c.frequency
        kp, ki, v_ff, v_max, dt = c.kp, c.ki, c.v_ff, c.v_max, dt_control or c.dt
        label = label or f"closed loop ({mode}, surrogate)"
    else:
        kp, ki, v_ff, v_max = 0.0, 0.0, float(controller), float(abs(controller))
        x_ref, F = (0.0 if x_ref is None else float(x_ref)), (0.0 if F is None else F)
        mode, frequency = mode or "dc", frequency or 10.0
        dt = dt_control or control_step(frequency, mode)
        label = label or f"open loop {controller:.0f} V ({mode}, surrogate)"
    if callable(F):
        raise ValueError("F: the compiled loop takes a constant load (N); for a load that varies in time use "
                         "simulate_hold")
    if mode not in MODES:
        raise ValueError(f"mode: got {mode!r}, expected one of {', '.join(MODES)}")
    n, half = _samples(duration, dt, mode, frequency)
    ctl = np.array([x_ref, kp, ki, v_ff, v_max, dt, float(F)], float)
    out = np.empty((n + 1, 5))
    wall = time.perf_counter()
    status, k, steps, y = sk.pi_loop(np.zeros(s.ny), s.tables, s.par(), s._law, s._lawp, s.scales(max(v_ff, v_max)),
                                     float(rtol or RTOL), ctl, int(n), int(half), int(1_000_000), out)
    wall = time.perf_counter() - wall
    if status != sk.OK:
        raise SurrogateError(f"surrogate hold stopped at t = {k * dt:g} s (integrator status {status})")
    C = s.capacitance(out[:, 1])
    return HoldResult(label, out[:, 0].copy(), out[:, 1].copy(), out[:, 2].copy(), out[:, 3].copy(),
                      np.full(n + 1, float(F)), out[:, 4].copy(), C, wall_time=wall)


def check_hold(controller: HoldController, duration: float, t_skip: float = 2.0) -> None:
    """ValueError naming the argument unless compare_hold can run `controller` for
    `duration` s: longer than t_skip (the metrics are taken after it), a whole number of
    its control steps, and within the stated limit of steps (limits.MAX_SEGMENTS)."""
    if not duration > t_skip:
        raise ValueError(f"duration: got {duration:g} s, expected more than t_skip = {t_skip:g} s (the metrics are "
                         f"taken after the first {t_skip:g} s)")
    _samples(duration, controller.dt, controller.mode, controller.frequency)


def compare_hold(params_or_model, controller: HoldController, duration: float = 300.0, *, x_ref=None, F=None,
                 t_skip: float = 2.0, include_dc_loop: bool = False, v_open: float | None = None) -> dict:
    """The same long hold on the full model under: open-loop DC at v_open, fixed-frequency
    inversion (the controller's frequency) at v_open, and the closed loop; with
    include_dc_loop also the DC amplitude-adaptation loop (same gains, mode 'dc').
    v_open: default the full model's static voltage for x_ref under the initial load.
    Returns {'v_open', 'x_ref', 'runs': {name: HoldResult}, 'metrics': {name: dict}}."""
    check_hold(controller, duration, t_skip)
    model = params_or_model if isinstance(params_or_model, DFAModel) else DFAModel(params_or_model)
    x_ref = controller.x_ref if x_ref is None else x_ref
    F = controller.F if F is None else F
    F0 = F(0.0) if callable(F) else F
    if v_open is None:
        v_open = feedforward_voltage(model, x_ref, F0)
    runs = {
        "open-loop DC": simulate_hold(model, v_open, x_ref, F, duration, controller.dt, mode="dc",
                                      label="open-loop DC"),
        "inversion": simulate_hold(model, v_open, x_ref, F, duration, controller.dt, mode="bipolar",
                                   frequency=controller.frequency, label=f"inversion {controller.frequency:g} Hz"),
        "closed loop": simulate_hold(model, controller, x_ref, F, duration, label="closed loop"),
    }
    if include_dc_loop:
        dc = dataclasses.replace(controller, mode="dc")
        runs["DC loop"] = simulate_hold(model, dc, x_ref, F, duration, label="DC amplitude loop")
    return {"v_open": v_open, "x_ref": x_ref, "runs": runs,
            "metrics": {k: r.metrics(x_ref, t_skip, period=1.0 / controller.frequency) for k, r in runs.items()}}


# ---------------------------------------------------------------------- FMU
def cosim_hold_fmu(fmu_path, controller: HoldController, x_ref: float | None = None, F=None, duration: float = 60.0,
                   dt: float | None = None, *, v_nominal: float = 6000.0, exact: bool = True,
                   start: dict | None = None) -> HoldResult:
    """The loop of simulate_hold closed around the actuator FMU (dfa fmu build) by a
    Python master under fmpy (fmu.cosim's FMU2Slave wrapper): every dt, read the stroke,
    compute the amplitude, set voltage and force, doStep. v_nominal / exact go to the
    FMU's parameters v_nominal / land_on_communication_points; `start`: other start
    values."""
    from fmu.cosim import _Unit
    law, mode, frequency, dt_c = _law_for(controller, x_ref)
    dt = dt or dt_c
    F = controller.F if F is None else F
    unit = _Unit(fmu_path, "actuator", {"v_nominal": float(v_nominal), "land_on_communication_points": bool(exact),
                                        **(start or {})}, duration)
    names = ("stroke", "current", "capacitance")
    try:
        def step(t, h, V, f):
            unit.set(("voltage", "force"), (V, f))
            unit.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)

        def read():
            return tuple(unit.get(names))

        return _run_loop(step, read, law, mode, frequency, F, duration, dt, "closed loop (FMU)")
    finally:
        unit.close()
