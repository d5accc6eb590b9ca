"""Design of a polarity-inversion drive: the frequency window that holds the stroke.

    from reduced.design import design_inversion
    d = design_inversion(reduced.build(p, "charge"), V=6000, F=5, max_ripple=50e-6, max_drift=20e-6,
                         horizon=600, current_limit=10e-3)
    d.frequency, d.f_min, d.f_max, d.power, d.verified

A bipolar trapezoid (averaged.BipolarTrapezoid: +V for `duty` of each period, -V for
the rest, ramps of t_ramp through zero) held for `horizon` s against a load F. With the
definitions of averaged.py:

    ripple  peak-to-peak stroke over the last whole period of the horizon (m)
    drift   x_static - x_mean_end (m), x_static the uncharged static stroke
            (dfa_model.statics.equilibrium_stroke)

Low frequencies let the interface charge follow each polarity (ripple grows like 1/f,
and the charge's slow mean drifts); high frequencies spend more of the time in the
ramps, where the stroke sags towards zero force (drift grows like f t_ramp). The ramp:
t_ramp = max(2 V / slew_rate, 2 V C / current_limit), C the device capacitance at the
static stroke (the full model's diagnostics at fixed interface charge), so the source
must move the charge 2 C V within each inversion.

Method: the averaged surrogate (averaged.simulate_averaged: one averaged kernel run over
the horizon, then the last periods of the real waveform) on a log grid of frequencies
(`n_grid`, default 30) between f_range (clipped to at least one period in the horizon
and to ramps that fit in each polarity's share); the largest contiguous feasible run
(ripple <= max_ripple and |drift| <= max_drift) is the window; its two edges are refined
by bisection on log f to 2 %. Recommended frequency: min(f_max, 1.25 f_min) (25 %
margin above the edge, the least power). Power: each inversion moves the charge 2 C V
through the source at V, 2 C V^2 per inversion and two per period: P = 4 f C V^2 (W),
leakage neglected. `verify=True` runs the full model (dfa_model.simulate) on the same
waveform over the whole horizon at the recommended frequency; where it misses the limits
the recommendation moves into the window by steps of 1.25x (at most 6, each checked on
the full model) and the reason says so: the answer holds on the full model or is
flagged (verified['meets'] False).
"""
from __future__ import annotations

import json
import math
import sys
import time
import warnings
from dataclasses import asdict, dataclass, field

import numpy as np

from . import averaged

DUTY_RANGE = (0.3, 0.7)
REFINE = 0.02     # relative width at which an edge's bisection stops
VERIFY_STEP, VERIFY_TRIES = 1.25, 6   # a recommendation the full model rejects moves this way into the window


@dataclass
class InversionDesign:
    """The result of design_inversion (also readable as a dict: d['f_min'])."""

    feasible: bool
    reason: str
    f_min: float | None
    f_max: float | None
    frequency: float | None
    duty: float
    power: float | None
    ripple: float | None
    drift: float | None
    verified: dict | None
    V: float = 0.0
    F: float = 0.0
    horizon: float = 0.0
    max_ripple: float = 0.0
    max_drift: float = 0.0
    t_ramp: float = 0.0
    capacitance: float = 0.0
    x_static: float = 0.0
    f_searched: tuple = (0.0, 0.0)
    scan: dict = field(default_factory=dict)
    wall_time: float = 0.0

    KEYS = ("f_min", "f_max", "frequency", "duty", "power", "ripple", "drift", "verified", "feasible", "reason")

    def __getitem__(self, key):
        return getattr(self, key)

    def keys(self):
        return self.KEYS

    def to_dict(self, full=False) -> dict:
        if full:
            d = asdict(self)
            d["scan"] = {k: list(map(float, v)) for k, v in self.scan.items()}
            return d
        return {k: getattr(self, k) for k in self.KEYS}


# ---------------------------------------------------------------------- checks
def _num(name, value, lo, hi=None, lo_open=True, unit=""):
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: got {value!r}, expected a number") from None
    rng = f"{'>' if lo_open else '>='} {lo:g} {unit}".rstrip() if hi is None else \
        f"in {'(' if lo_open else '['}{lo:g}, {hi:g}] {unit}".rstrip()
    bad = not math.isfinite(v) or v < lo or (lo_open and v == lo) or (hi is not None and v > hi)
    if bad:
        raise ValueError(f"{name}: got {value!r}, expected a value {rng}")
    return v


def check_arguments(V, F, max_ripple, max_drift, horizon, slew_rate=None, current_limit=None, duty=0.5,
                    f_range=(0.01, 1000.0)):
    """The design's arguments as floats, or ValueError naming the argument and its range."""
    V = _num("V", V, 0.0, 1e6, unit="V")
    try:
        F = float(F)
    except (TypeError, ValueError):
        raise ValueError(f"F: got {F!r}, expected a finite number (N)") from None
    if not (math.isfinite(F) and abs(F) <= 1e6):
        raise ValueError(f"F: got {F!r}, expected a finite number of magnitude <= 1e6 N")
    max_ripple = _num("max_ripple", max_ripple, 0.0, unit="m")
    max_drift = _num("max_drift", max_drift, 0.0, unit="m")
    horizon = _num("horizon", horizon, 0.0, 1e7, unit="s")
    if slew_rate is not None:
        slew_rate = _num("slew_rate", slew_rate, 0.0, unit="V/s")
    if current_limit is not None:
        current_limit = _num("current_limit", current_limit, 0.0, unit="A")
    duty = _num("duty", duty, DUTY_RANGE[0], DUTY_RANGE[1], lo_open=False)
    try:
        f_lo, f_hi = (float(v) for v in f_range)
    except (TypeError, ValueError):
        raise ValueError(f"f_range: got {f_range!r}, expected (f_low, f_high) in Hz") from None
    if not (math.isfinite(f_lo) and math.isfinite(f_hi) and 0 < f_lo < f_hi <= 1e6):
        raise ValueError(f"f_range: got {f_range!r}, expected 0 < f_low < f_high <= 1e6 Hz")
    return V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, duty, (f_lo, f_hi)


def device_capacitance(params, x, V) -> float:
    """Capacitance (F) at stroke x, uncharged (the full model's diagnostics column R_C:
    capacitance at fixed interface charge)."""
    from dfa_model.equations import R_C
    from dfa_model.statics import static_state

    from . import frozen
    model = frozen.as_model(params) if not hasattr(params, "diagnostics") else params
    return float(model.diagnostics(static_state(model, x, V), V)[0][R_C])


def inversion_power(f, C, V) -> float:
    """Source power (W) of polarity inversion: 2 C V^2 per inversion, 2 per period."""
    return 4.0 * f * C * V * V


# ---------------------------------------------------------------------- design
def design_inversion(s, V, F, max_ripple, max_drift, horizon, slew_rate=None, current_limit=None, duty=0.5,
                     f_range=(0.01, 1000.0), verify=True, n_grid=30, balanced=True) -> InversionDesign:
    """The frequency window of a bipolar drive at amplitude V (duty: share of the period
    at +V) that keeps surrogate `s`'s stroke against load F within max_ripple (m,
    peak-to-peak over the last period) and max_drift (m, stroke lost against the
    uncharged static stroke) at the end of `horizon` s; the recommended frequency, its
    power and, with verify=True, the full model's check (module docstring). balanced:
    start the drive at the charge-balanced phase (averaged.balanced_phase), as
    recommended; False starts at phase 0 (see the module docstring for what that costs)."""
    wall = time.perf_counter()
    V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, duty, (f_lo, f_hi) = check_arguments(
        V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, duty, f_range)
    if not isinstance(n_grid, int) or not 3 <= n_grid <= 1000:
        raise ValueError(f"n_grid: got {n_grid!r}, expected an integer in [3, 1000]")
    params = s.params
    x_static = averaged.static_stroke(params, V, F)
    base = {"duty": duty, "V": V, "F": F, "horizon": horizon, "max_ripple": max_ripple, "max_drift": max_drift,
                "x_static": x_static}

    def infeasible(reason, **kw):
        out = {"feasible": False, "reason": reason, "f_min": None, "f_max": None, "frequency": None, "power": None, "ripple": None,
                   "drift": None, "verified": None}
        out.update(base)
        out.update(kw)
        return InversionDesign(**out, wall_time=time.perf_counter() - wall)

    if x_static <= 0.0:
        return infeasible(f"{V:g} V cannot zip against {F:g} N: no stroke to hold")
    C = device_capacitance(params, x_static, V)
    t_ramp = averaged.ramp_time(V, slew_rate, current_limit, C)
    base.update(t_ramp=t_ramp, capacitance=C)
    lo = max(f_lo, 1.0 / horizon)
    hi = min(f_hi, averaged.max_frequency(duty, t_ramp))
    base["f_searched"] = (lo, hi)
    if not lo < hi:
        why = []
        if 1.0 / horizon >= f_hi:
            why.append(f"a horizon of {horizon:g} s holds no whole period below {f_hi:g} Hz")
        if averaged.max_frequency(duty, t_ramp) <= f_lo:
            why.append(f"ramps of {t_ramp:g} s do not fit in a period above {f_lo:g} Hz")
        return infeasible("no frequency to search: " + "; ".join(why or ["empty range"]))

    cache = {}

    def ev(f):
        if f not in cache:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = averaged.simulate_averaged(s, V, F, f, duty, horizon, t_ramp, balanced=balanced,
                                               x_static=x_static)
            cache[f] = (r.ripple, r.drift)
        return cache[f]

    def ok(f):
        rip, dr = ev(f)
        return rip <= max_ripple and abs(dr) <= max_drift

    fs = np.geomspace(lo, hi, n_grid)
    good = np.array([ok(f) for f in fs])
    rip = np.array([cache[f][0] for f in fs])
    dri = np.array([cache[f][1] for f in fs])
    base["scan"] = {"frequency": fs, "ripple": rip, "drift": dri}
    if not good.any():
        i_r, i_d = int(np.argmin(rip)), int(np.argmin(np.abs(dri)))
        parts = []
        if rip.min() > max_ripple:
            parts.append(f"the ripple never falls to {max_ripple * 1e6:.3g} um (least {rip.min() * 1e6:.3g} um at "
                         f"{fs[i_r]:.3g} Hz" + (f"; ramps of {t_ramp * 1e3:.3g} ms let the stroke sag at each "
                                               f"zero crossing: a faster source lowers it)" if t_ramp > 0 else ")"))
        if np.abs(dri).min() > max_drift:
            parts.append(f"the drift never falls to {max_drift * 1e6:.3g} um (least {np.abs(dri).min() * 1e6:.3g} "
                         f"um at {fs[i_d]:.3g} Hz)")
        if not parts:
            parts.append(f"ripple and drift are never within limits at the same frequency in "
                         f"[{lo:.3g}, {hi:.3g}] Hz")
        return infeasible("; ".join(parts))
    # the largest contiguous feasible run of the grid (the lowest one on a tie)
    runs, i = [], 0
    while i < n_grid:
        if good[i]:
            j = i
            while j + 1 < n_grid and good[j + 1]:
                j += 1
            runs.append((i, j))
            i = j + 1
        else:
            i += 1
    i0, i1 = max(runs, key=lambda r: (r[1] - r[0], -r[0]))

    def edge(f_bad, f_good):
        while abs(math.log(f_good / f_bad)) > math.log1p(REFINE):
            fm = math.sqrt(f_bad * f_good)
            if ok(fm):
                f_good = fm
            else:
                f_bad = fm
        return f_good

    notes = []
    f_min = fs[i0] if i0 == 0 else edge(fs[i0 - 1], fs[i0])
    f_max = fs[i1] if i1 == n_grid - 1 else edge(fs[i1 + 1], fs[i1])
    if i0 == 0:
        notes.append(f"f_min is the searched range's lower end ({lo:.3g} Hz)")
    if i1 == n_grid - 1:
        notes.append(f"f_max is the searched range's upper end ({hi:.3g} Hz" +
                     (", where the ramps fill each polarity's share)" if hi < f_hi else ")"))
    if len(runs) > 1:
        notes.append(f"{len(runs)} separate feasible bands on the grid: the widest is reported")
    frequency = min(f_max, 1.25 * f_min)
    r_rec, d_rec = ev(frequency)
    verified = None
    if verify:
        t0 = time.perf_counter()

        def check(f):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                _, rf, df = averaged.simulate_full(params, V, F, f, duty, horizon, t_ramp, balanced=balanced,
                                                   x_static=x_static)
            return rf, df, bool(rf <= max_ripple and abs(df) <= max_drift)

        rf, df, meets = check(frequency)
        if not meets:
            # the surrogate is off near this edge: walk into the window (up from the low
            # edge, down from the high one) until the full model meets the limits too
            f0, step = frequency, (VERIFY_STEP if frequency < math.sqrt(f_min * f_max) else 1.0 / VERIFY_STEP)
            f = frequency
            for _ in range(VERIFY_TRIES):
                f *= step
                if not f_min <= f <= f_max:
                    break
                rf2, df2, ok2 = check(f)
                if ok2:
                    frequency, rf, df, meets = f, rf2, df2, True
                    r_rec, d_rec = ev(frequency)
                    notes.append(f"moved from {f0:.3g} Hz, where the full model misses the limits, to {f:.3g} Hz, "
                                 f"where it meets them (the surrogate is off near the window's edge)")
                    break
        verified = {"frequency": frequency, "ripple": rf, "drift": df, "meets": meets,
                    "wall_time": time.perf_counter() - t0}
        if not meets:
            notes.append("the full model does NOT meet the limits at the recommended frequency nor at "
                         f"{VERIFY_TRIES} steps of {VERIFY_STEP:g}x into the window: the surrogate is off here "
                         "(fit it: reduced.fit)")
    base.update(feasible=True, reason="; ".join(notes) or "ok", f_min=float(f_min), f_max=float(f_max),
                frequency=float(frequency), power=inversion_power(frequency, C, V), ripple=r_rec, drift=d_rec,
                verified=verified)
    return InversionDesign(**base, wall_time=time.perf_counter() - wall)


# ---------------------------------------------------------------------- dfa design
def add_design_parser(subparsers):
    """`dfa design`: the subcommand's flags (register with the dfa command's subparsers)."""
    from dfa_model import cli as base
    pd = subparsers.add_parser("design", help="polarity-inversion frequency window that holds the stroke")
    base._add_params_flags(pd)
    pd.add_argument("--voltage", type=base._number(0.0, 1e6, lo_open=True), required=True, metavar="V",
                    help="amplitude, V")
    pd.add_argument("--force", type=base._number(-1e6, 1e6), required=True, metavar="F", help="load, N")
    pd.add_argument("--max-ripple", type=base._number(0.0, lo_open=True), required=True, metavar="M",
                    help="peak-to-peak stroke over the last period, m")
    pd.add_argument("--max-drift", type=base._number(0.0, lo_open=True), required=True, metavar="D",
                    help="stroke lost against the uncharged static stroke by the end of the horizon, m")
    pd.add_argument("--horizon", type=base._number(0.0, 1e7, lo_open=True), required=True, metavar="S",
                    help="how long the stroke must be held, s")
    pd.add_argument("--slew-rate", type=base._number(0.0, lo_open=True), metavar="V_PER_S",
                    help="the source's slew rate, V/s (default: ideal switching)")
    pd.add_argument("--current-limit", type=base._number(0.0, lo_open=True), metavar="A",
                    help="the source's current limit, A")
    pd.add_argument("--family", choices=["charge", "lumped"], default="charge", help="surrogate family")
    pd.add_argument("--json", action="store_true", help="print the design as one JSON object (last line)")
    pd.set_defaults(func=design_command)
    return pd


def design_command(args) -> int:
    """`dfa design`: build the surrogate, design, print a summary (and JSON)."""
    from dfa_model import cli as base

    from .cli import json_safe
    from .families import build
    p = base._params(args)
    s = build(p, args.family)
    d = design_inversion(s, args.voltage, args.force, args.max_ripple, args.max_drift, args.horizon,
                         slew_rate=args.slew_rate, current_limit=args.current_limit)
    out = sys.stdout

    def um(v):
        return "-" if v is None else f"{v * 1e6:.2f} um"
    print(f"polarity inversion at {d.V:g} V, {d.F:g} N, held {d.horizon:g} s, duty {d.duty:g} "
          f"({args.family} surrogate)", file=out)
    print(f"  static stroke {d.x_static * 1e3:.4f} mm, capacitance {d.capacitance * 1e12:.1f} pF, "
          f"ramp {d.t_ramp * 1e3:.4g} ms per inversion", file=out)
    print(f"  limits: ripple <= {um(d.max_ripple)}, drift <= {um(d.max_drift)}", file=out)
    if d.feasible:
        print(f"  window   {d.f_min:.4g} - {d.f_max:.4g} Hz", file=out)
        print(f"  use      {d.frequency:.4g} Hz: ripple {um(d.ripple)}, drift {um(d.drift)}, power "
              f"{d.power * 1e3:.3g} mW", file=out)
        if d.verified:
            v = d.verified
            print(f"  full model at {d.frequency:.4g} Hz: ripple {um(v['ripple'])}, drift {um(v['drift'])}: "
                  f"{'meets' if v['meets'] else 'DOES NOT MEET'} the limits ({v['wall_time']:.2f} s)", file=out)
        if d.reason != "ok":
            print(f"  note: {d.reason}", file=out)
    else:
        print(f"  no frequency meets the limits: {d.reason}", file=out)
    print(f"  wall time {d.wall_time:.2f} s", file=out)
    if args.json:
        print(json.dumps(json_safe(d.to_dict())), file=out)
    return 0
