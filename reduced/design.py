"""Design of a polarity-inversion drive: the frequency window that holds the stroke.

    from reduced.design import design_inversion
    d = design_inversion(reduced.build(p, "charge"), V=6000, F=5, max_ripple=50e-6, max_drift=20e-6,
                         horizon=600, current_limit=10e-3)
    d.frequency, d.f_min, d.f_max, d.power, d.verified
    d.protocol().save("drive.toml")          # the drive as designed: `dfa simulate --protocol drive.toml`

The drive: full-duty inversion (dfa_model.Bipolar with duty 1: no dead time; `duty` has
Bipolar's meaning everywhere), +V for `positive_share` of each period and -V for the
rest, each inversion a ramp of t_ramp through zero centred on its instant, started at
the charge-balanced phase (waveforms.balanced_phase), held for `horizon` s against a load
F. With the words of README, 'Words with one meaning':

    ripple  peak-to-peak stroke over the last whole period of the horizon (m)
    drift   stroke lost: x_static - the mean stroke over that period (m, positive when
            lost), x_static the uncharged static stroke (dfa_model.physics.statics.equilibrium_stroke)

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
margin above the edge, the least power). `verify=True` runs the full model
(dfa_model.simulate) on the same drive over the whole horizon at the recommended
frequency; where it misses the limits the recommendation moves into the window by steps
of 1.25x (at most 6, each checked on the full model) and the reason says so: the answer
holds on the full model or is flagged (verified['meets'] False). A horizon of more than
VERIFY_PERIODS periods is not checked (verified None, and the reason says so).

Power, two quantities (`power`, W):
    hard_switched_dissipation  4 f C V^2: a source that switches hard (no ramps) moves
                               2 C V through V at each inversion, two per period, and
                               dissipates it (leakage neglected);
    input                      what the source delivers to the actuator with the drive as
                               designed (its ramps): the full model's input energy over the
                               last period of the verification run, per second (None
                               without verification). With slow ramps the charge comes
                               back to the source at each inversion: far below the first.
"""
from __future__ import annotations

import math
import time
import warnings
from dataclasses import asdict, dataclass, field

import numpy as np

from . import averaged

SHARE_RANGE = (0.3, 0.7)   # share of the period at +V the design takes
REFINE = 0.02     # relative width at which an edge's bisection stops
VERIFY_STEP, VERIFY_TRIES = 1.25, 6   # a recommendation the full model rejects moves this way into the window
# the full model's check runs the whole horizon: at most this many periods (seconds at N = 81
# even with ramps, a sixth of the step limit); a longer one is not checked, and the reason says so
VERIFY_PERIODS = 20_000


@dataclass
class InversionDesign:
    """The result of design_inversion (also readable as a dict: d['f_min'])."""

    feasible: bool
    reason: str
    f_min: float | None
    f_max: float | None
    frequency: float | None
    power: dict | None
    ripple: float | None
    drift: float | None
    verified: dict | None
    duty: float = 1.0               # Bipolar's duty: full-duty inversion, no dead time
    positive_share: float = 0.5
    phase: float | None = None      # the drive's start (share of a period): the charge-balanced phase
    balanced: bool = True
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
    checks: list = field(default_factory=list)    # every full-model check: {frequency, ripple, drift, meets}
    wall_time: float = 0.0

    KEYS = ("f_min", "f_max", "frequency", "duty", "positive_share", "slew_rate", "phase", "power", "ripple", "drift",
            "verified", "feasible", "reason")

    def __getitem__(self, key):
        return getattr(self, key)

    def keys(self):
        return self.KEYS

    @property
    def slew_rate(self) -> float | None:
        """The drive's slew rate (V/s): 2 V / t_ramp; None for ideal switching."""
        return 2.0 * abs(self.V) / self.t_ramp if self.t_ramp > 0 else None

    def drive(self, frequency=None):
        """The drive (dfa_model.Bipolar) at the recommended frequency (or `frequency`)."""
        f = self.frequency if frequency is None else frequency
        if f is None:
            raise ValueError(f"no drive: the design is infeasible ({self.reason})")
        return averaged.drive(self.V, f, self.positive_share, self.t_ramp, self.balanced)

    def protocol(self, frequency=None):
        """The drive as designed over the horizon (whole periods, as verified) with its load:
        protocol.save('drive.toml') writes it for `dfa simulate --protocol`, `dfa compare`
        and the FMU system's drive (`dfa fmu build --system --drive`)."""
        from dfa_model.waveforms import Load, Protocol, Stage
        wave = self.drive(frequency)
        return Protocol([Stage(wave, averaged.whole_periods(self.horizon, wave.frequency), "hold")],
                        load=Load(self.F))

    def to_dict(self, full=False) -> dict:
        if full:
            d = asdict(self)
            d["scan"] = {k: list(map(float, v)) for k, v in self.scan.items()}
            d["slew_rate"] = self.slew_rate
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


def check_arguments(V, F, max_ripple, max_drift, horizon, slew_rate=None, current_limit=None, positive_share=0.5,
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
    positive_share = _num("positive_share", positive_share, SHARE_RANGE[0], SHARE_RANGE[1], lo_open=False)
    try:
        f_lo, f_hi = (float(v) for v in f_range)
    except (TypeError, ValueError):
        raise ValueError(f"f_range: got {f_range!r}, expected (f_low, f_high) in Hz") from None
    if not (math.isfinite(f_lo) and math.isfinite(f_hi) and 0 < f_lo < f_hi <= 1e6):
        raise ValueError(f"f_range: got {f_range!r}, expected 0 < f_low < f_high <= 1e6 Hz")
    return V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, positive_share, (f_lo, f_hi)


def device_capacitance(params, x, V) -> float:
    """Capacitance (F) at stroke x, uncharged (the full model's diagnostics column R_C:
    capacitance at fixed interface charge)."""
    from dfa_model.physics.equations import R_C
    from dfa_model.physics.statics import static_state

    from . import frozen
    model = frozen.as_model(params) if not hasattr(params, "diagnostics") else params
    return float(model.diagnostics(static_state(model, x, V), V)[0][R_C])


def inversion_power(f, C, V) -> float:
    """What a hard-switched source dissipates (W) in polarity inversion: it moves 2 C V
    through V at each inversion, two per period: 4 f C V^2 (leakage neglected)."""
    return 4.0 * f * C * V * V


# ---------------------------------------------------------------------- design
def design_inversion(s, V, F, max_ripple, max_drift, horizon, slew_rate=None, current_limit=None,
                     positive_share=0.5, f_range=(0.01, 1000.0), verify=True, n_grid=30, balanced=True,
                     duty=None, params=None) -> InversionDesign:
    """The frequency window of full-duty polarity inversion at amplitude V that keeps
    surrogate `s`'s stroke against load F within max_ripple (m, peak-to-peak over the
    last period) and max_drift (m, stroke lost against the uncharged static stroke) at
    the end of `horizon` s; the recommended frequency, its power and, with verify=True,
    the full model's check (module docstring). positive_share: the share of each period
    at +V (0.5: symmetric). balanced: start the drive at the charge-balanced phase, as
    recommended; False starts at phase 0 (what that costs: README, 'Surrogates').
    `duty` is not a parameter of the design: it was the share of the period at +V,
    which is positive_share now (duty is Bipolar's: the designed drive has duty 1).
    params: the full model's parameters for x_static and the checks (default the
    surrogate's own; the same device at another discretization, say)."""
    wall = time.perf_counter()
    if duty is not None:
        raise TypeError("design_inversion: duty is not an argument: the design's drive is full-duty inversion "
                        "(Bipolar duty 1, no dead time); the share of each period at +V is positive_share")
    V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, share, (f_lo, f_hi) = check_arguments(
        V, F, max_ripple, max_drift, horizon, slew_rate, current_limit, positive_share, f_range)
    if not isinstance(n_grid, int) or not 3 <= n_grid <= 1000:
        raise ValueError(f"n_grid: got {n_grid!r}, expected an integer in [3, 1000]")
    params = s.params if params is None else params
    x_static = averaged.static_stroke(params, V, F)
    base = {"positive_share": share, "balanced": bool(balanced), "V": V, "F": F, "horizon": horizon,
            "max_ripple": max_ripple, "max_drift": max_drift, "x_static": x_static}

    def result(feasible, reason, **kw):
        out = {"f_min": None, "f_max": None, "frequency": None, "power": None, "ripple": None, "drift": None,
               "verified": None, **base, **kw}
        return InversionDesign(feasible=feasible, reason=reason, **out, wall_time=time.perf_counter() - wall)

    if x_static <= 0.0:
        return result(False, f"{V:g} V cannot zip against {F:g} N: no stroke to hold")
    C = device_capacitance(params, x_static, V)
    t_ramp = averaged.ramp_time(V, slew_rate, current_limit, C)
    base.update(t_ramp=t_ramp, capacitance=C)
    lo = max(f_lo, 1.0 / horizon)
    hi = min(f_hi, averaged.max_frequency(share, t_ramp))
    base["f_searched"] = (lo, hi)
    if not lo < hi:
        why = []
        if 1.0 / horizon >= f_hi:
            why.append(f"a horizon of {horizon:g} s holds no whole period below {f_hi:g} Hz")
        if averaged.max_frequency(share, t_ramp) <= f_lo:
            why.append(f"ramps of {t_ramp:g} s do not fit in a period above {f_lo:g} Hz")
        return result(False, "no frequency to search: " + "; ".join(why or ["empty range"]))

    scan = _Scan(s, V, F, share, horizon, t_ramp, balanced, x_static, max_ripple, max_drift)
    window = scan.window(lo, hi, n_grid)
    base["scan"] = scan.grid
    if window is None:
        return result(False, scan.why_infeasible(t_ramp))
    f_min, f_max, notes = window
    if share != 0.5:
        notes.append("an unequal share: the surrogate's drift under the mean voltage is a stated breakdown "
                     "(docs/guide/surrogates.md); trust the full model's check (verified)")
    frequency = min(f_max, 1.25 * f_min)
    verified, checks = None, []
    if verify and frequency * horizon > VERIFY_PERIODS:
        notes.append(f"not checked on the full model: {frequency * horizon:.3g} periods over the horizon, more than "
                     f"the {VERIFY_PERIODS} it is run for (replay the drive: dfa simulate --protocol)")
    elif verify:
        frequency, verified, checks = _verify(params, scan, frequency, f_min, f_max, notes)
        base["checks"] = checks
    rip, dr = scan(frequency)
    wave = averaged.drive(V, frequency, share, t_ramp, balanced)
    power = {"hard_switched_dissipation": inversion_power(frequency, C, V),
             "input": verified["input_power"] if verified else None}
    return result(True, "; ".join(notes) or "ok", f_min=float(f_min), f_max=float(f_max),
                  frequency=float(frequency), phase=float(wave.phase), power=power, ripple=rip, drift=dr,
                  verified=verified)


class _Scan:
    """The averaged surrogate's (ripple, drift) at a frequency, cached, and the window it
    gives over a grid (the module docstring's method)."""

    def __init__(self, s, V, F, share, horizon, t_ramp, balanced, x_static, max_ripple, max_drift):
        self.s, self.V, self.F, self.positive_share, self.horizon = s, V, F, share, horizon
        self.t_ramp, self.balanced, self.x_static = t_ramp, balanced, x_static
        self.max_ripple, self.max_drift = max_ripple, max_drift
        self.cache, self.grid = {}, {}
        # the surrogate's drift is measured against its own uncharged statics (the charge
        # family's are the full model's; the lumped circuit's differ by its force map),
        # the full model's checks against the full model's (x_static)
        self.x_static_model = float(s.equilibrium(V, F)[0])

    def __call__(self, f):
        if f not in self.cache:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                r = averaged.simulate_averaged(self.s, self.V, self.F, f, self.positive_share, self.horizon, self.t_ramp,
                                               balanced=self.balanced, x_static=self.x_static_model)
            self.cache[f] = (r.ripple, r.drift)
        return self.cache[f]

    def ok(self, f) -> bool:
        rip, dr = self(f)
        return rip <= self.max_ripple and abs(dr) <= self.max_drift

    def window(self, lo, hi, n_grid):
        """(f_min, f_max, notes) of the largest contiguous feasible run of a log grid over
        [lo, hi], its inner edges refined by bisection; None if no grid point is feasible."""
        fs = np.geomspace(lo, hi, n_grid)
        good = np.array([self.ok(f) for f in fs])
        self.grid = {"frequency": fs, "ripple": np.array([self.cache[f][0] for f in fs]),
                     "drift": np.array([self.cache[f][1] for f in fs])}
        if not good.any():
            return None
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
        i0, i1 = max(runs, key=lambda r: (r[1] - r[0], -r[0]))      # the widest; the lowest on a tie
        notes = []
        f_min = fs[i0] if i0 == 0 else self._edge(fs[i0 - 1], fs[i0])
        f_max = fs[i1] if i1 == n_grid - 1 else self._edge(fs[i1 + 1], fs[i1])
        if i0 == 0:
            notes.append(f"f_min is the searched range's lower end ({lo:.3g} Hz)")
        if i1 == n_grid - 1:
            notes.append(f"f_max is the searched range's upper end ({hi:.3g} Hz" +
                         (", where the ramps fill each polarity's share)" if self.t_ramp > 0 and
                          hi >= averaged.max_frequency(self.positive_share, self.t_ramp) * (1 - 1e-9) else ")"))
        if len(runs) > 1:
            notes.append(f"{len(runs)} separate feasible bands on the grid: the widest is reported")
        return f_min, f_max, notes

    def _edge(self, f_bad, f_good):
        while abs(math.log(f_good / f_bad)) > math.log1p(REFINE):
            fm = math.sqrt(f_bad * f_good)
            if self.ok(fm):
                f_good = fm
            else:
                f_bad = fm
        return f_good

    def why_infeasible(self, t_ramp) -> str:
        fs, rip, dri = self.grid["frequency"], self.grid["ripple"], self.grid["drift"]
        i_r, i_d = int(np.argmin(rip)), int(np.argmin(np.abs(dri)))
        parts = []
        if rip.min() > self.max_ripple:
            parts.append(f"the ripple never falls to {self.max_ripple * 1e6:.3g} um (least {rip.min() * 1e6:.3g} um at "
                         f"{fs[i_r]:.3g} Hz" + (f"; ramps of {t_ramp * 1e3:.3g} ms let the stroke sag at each "
                                               f"zero crossing: a faster source lowers it)" if t_ramp > 0 else ")"))
        if np.abs(dri).min() > self.max_drift:
            parts.append(f"the drift never falls to {self.max_drift * 1e6:.3g} um (least "
                         f"{np.abs(dri).min() * 1e6:.3g} um at {fs[i_d]:.3g} Hz)")
        return "; ".join(parts or [f"ripple and drift are never within limits at the same frequency in "
                                   f"[{fs[0]:.3g}, {fs[-1]:.3g}] Hz"])


def full_check(params, spec, f) -> dict:
    """The full model on the designed drive at frequency f over the whole horizon: a row
    {frequency, ripple, drift, input_power, meets}. `spec`: a design or its scan (V, F,
    positive_share, horizon, t_ramp, balanced, x_static, max_ripple, max_drift)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res, rf, df = averaged.simulate_full(params, spec.V, spec.F, f, spec.positive_share, spec.horizon,
                                             spec.t_ramp, balanced=spec.balanced, x_static=spec.x_static, power=True)
    return {"frequency": float(f), "ripple": rf, "drift": df, "input_power": res.input_power(),
            "meets": bool(rf <= spec.max_ripple and abs(df) <= spec.max_drift)}


EDGE_PERIODS = 3000    # check_edges skips an edge whose run has more periods (tens of seconds of full model)


def check_edges(params, d: InversionDesign) -> list:
    """Add the full model's checks at the window's edges to d.checks (for the plot: where
    the surrogate's window ends against where the full model's does); an edge with more
    than EDGE_PERIODS periods over the horizon is skipped. Returns the skipped ones (Hz)."""
    skipped = []
    if d.feasible:
        for f in (d.f_min, d.f_max):
            if any(abs(c["frequency"] / f - 1) <= 1e-9 for c in d.checks):
                continue
            if f * d.horizon > EDGE_PERIODS:
                skipped.append(f)
            else:
                d.checks.append(full_check(params, d, f))
    return skipped


def _verify(params, scan: _Scan, frequency, f_min, f_max, notes):
    """The full model at the recommended frequency over the whole horizon; where it misses
    the limits, steps of VERIFY_STEP into the window (up from the low edge, down from
    the high one), each checked, until it meets them. Returns (frequency, verified, checks)."""
    t0 = time.perf_counter()
    checks = [full_check(params, scan, frequency)]
    row = checks[0]
    if not row["meets"]:
        f0, step = frequency, (VERIFY_STEP if frequency < math.sqrt(f_min * f_max) else 1.0 / VERIFY_STEP)
        f = frequency
        for _ in range(VERIFY_TRIES):
            f *= step
            if not f_min <= f <= f_max or f * scan.horizon > VERIFY_PERIODS:
                break
            checks.append(full_check(params, scan, f))
            if checks[-1]["meets"]:
                frequency, row = f, checks[-1]
                notes.append(f"moved from {f0:.3g} Hz, where the full model misses the limits, to {f:.3g} Hz, "
                             f"where it meets them (the surrogate is off near the window's edge)")
                break
    if not row["meets"]:
        notes.append("the full model does NOT meet the limits at the recommended frequency nor at "
                     f"{VERIFY_TRIES} steps of {VERIFY_STEP:g}x into the window: the surrogate is off here "
                     "(fit it: reduced.fit, or dfa reduce and --model)")
    verified = {**row, "wall_time": time.perf_counter() - t0}
    return frequency, verified, checks
