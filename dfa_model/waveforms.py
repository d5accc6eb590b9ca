"""Voltage waveforms, loads and protocols, as piecewise-linear signals.

Every signal becomes a list of segments on which it is linear in time; segment
boundaries are events for the integrator (it lands on them exactly), so square-wave
switches are resolved without stepping across them. A user callable is sampled on a
grid of `dt` and interpolated linearly (documented accuracy: that of the sampling).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .limits import MAX_DURATION, SIGNALS, check_segments, signal_value


# The protocol file's reader and writer: dfa_model.io.protocol_file, a layer above the
# drives it describes, registers itself here when the package is imported, so that
# Protocol.to_toml/save/from_toml reach it without an import running back up.
FILE_FORMAT: list = []


def register_file_format(module) -> None:
    FILE_FORMAT[:] = [module]


def _file_format():
    if not FILE_FORMAT:       # only if this module was loaded without its package
        raise RuntimeError("protocol files: import dfa_model (dfa_model.io.protocol_file) first")
    return FILE_FORMAT[0]


class WaveformError(ValueError):
    """Invalid waveform or protocol input (message names the field)."""


def _finite(name, value, lo=None, lo_incl=True, hi=None):
    try:
        value = float(value)
    except (TypeError, ValueError):
        raise WaveformError(f"{name}: got {value!r}, expected a number") from None
    if not math.isfinite(value):
        raise WaveformError(f"{name}: got {value!r}, expected a finite number")
    if lo is not None and (value < lo or (value == lo and not lo_incl)):
        rng = f"{'>=' if lo_incl else '>'} {lo:g}" + (f" and <= {hi:g}" if hi is not None else "")
        raise WaveformError(f"{name}: got {value!r}, expected a value {rng}")
    if hi is not None and value > hi:      # every digit: 10000001.0, not 1e+07, against <= 1e+07
        raise WaveformError(f"{name}: got {value!r}, expected a value <= {hi:g}")
    return value


def _level(name, value):
    """A finite signal value within the stated magnitude limit of its kind."""
    try:
        return signal_value(name, value)
    except ValueError as exc:
        raise WaveformError(str(exc)) from None


@dataclass
class Piecewise:
    """Linear on each [t[i], t[i+1]]: value v0[i] + slope[i] (t - t[i])."""

    t: np.ndarray
    v0: np.ndarray
    slope: np.ndarray

    def __call__(self, tq):
        tq = np.asarray(tq, float)
        i = np.clip(np.searchsorted(self.t, tq, side="right") - 1, 0, len(self.v0) - 1)
        return self.v0[i] + self.slope[i] * (tq - self.t[i])

    def shifted(self, dt):
        return Piecewise(self.t + dt, self.v0, self.slope)

    @staticmethod
    def concat(parts):
        t = [parts[0].t[:-1]]
        v0 = [parts[0].v0]
        sl = [parts[0].slope]
        for p in parts[1:]:
            t.append(p.t[:-1])
            v0.append(p.v0)
            sl.append(p.slope)
        t.append(parts[-1].t[-1:])
        return Piecewise(np.concatenate(t), np.concatenate(v0), np.concatenate(sl))


def merge(a: Piecewise, b: Piecewise):
    """Common breakpoints of two piecewise signals on the same span. A constant b over
    a's span (a constant load, the common case) adds no breakpoints and is not looked up."""
    const_b = len(b.v0) == 1 and b.slope[0] == 0.0 and b.t[0] <= a.t[0] and b.t[-1] >= a.t[-1]
    if const_b and len(a.t) > 1 and (a.t[1:] - a.t[:-1]).min() > 1e-13:
        # a's own breakpoints, already clean (every stock waveform's): its pieces as they are
        n = len(a.v0)
        return a.t, a.v0, a.slope, np.full(n, b.v0[0]), np.zeros(n)
    t = np.unique(a.t) if const_b else np.union1d(a.t, b.t)
    t = t[(t >= a.t[0]) & (t <= a.t[-1])]
    # drop breakpoints closer than 1e-13 s (float noise of periodic grids)
    keep = np.concatenate([[True], np.diff(t) > 1e-13])
    keep[-1] = True
    t = t[keep]
    if len(t) > 2 and t[-1] - t[-2] <= 1e-13:
        t = np.delete(t, -2)
    mid = 0.5 * (t[:-1] + t[1:])
    out = []
    for sig in (a, b):
        if sig is b and const_b:
            out.append((np.full(len(mid), b.v0[0]), np.zeros(len(mid))))
            continue
        i = np.clip(np.searchsorted(sig.t, mid, side="right") - 1, 0, len(sig.v0) - 1)
        v0 = sig.v0[i] + sig.slope[i] * (t[:-1] - sig.t[i])
        out.append((v0, sig.slope[i]))
    return t, out[0][0], out[0][1], out[1][0], out[1][1]


class Waveform:
    """A voltage signal starting at local time 0."""

    def piecewise(self, duration: float) -> Piecewise:
        raise NotImplementedError

    def __call__(self, t):
        t = np.asarray(t, float)
        return self.piecewise(float(np.max(t)) + 1e-9 if t.size else 1.0)(t)

    @property
    def amplitude(self) -> float:
        return abs(getattr(self, "V", 0.0))


@dataclass
class DC(Waveform):
    V: float

    def __post_init__(self):
        self.V = _level("voltage", self.V)

    def piecewise(self, duration):
        return Piecewise(np.array([0.0, duration]), np.array([self.V]), np.zeros(1))


class _Periodic(Waveform):
    """A periodic square wave of `frequency` (Hz) built from its switching instants.

    Each switch between two levels is centred on its ideal instant; with a finite
    `slew_rate` (V/s) it is a linear ramp taking |jump| / slew_rate (so the period mean
    is that of the ideal wave), otherwise a jump. `phase` (share of a period, [0, 1), or
    "balanced": balanced_phase) starts the drive that far into its period; phase 0
    starts at the first switch to the first level (the voltage before a protocol is 0)."""

    def _check_common(self):
        self.V = _level("voltage", self.V)
        self.frequency = _finite("frequency", self.frequency, 0.0, lo_incl=False, hi=1e6)
        self.duty = _finite("duty", self.duty, 0.0, lo_incl=False, hi=1.0)
        self.slew_rate = _finite("slew_rate", self.slew_rate, 0.0, lo_incl=False) if self.slew_rate is not None \
            and self.slew_rate != math.inf else None
        balanced = isinstance(self.phase, str)
        if balanced and self.phase != "balanced":
            raise WaveformError(f"phase: got {self.phase!r}, expected a share of a period in [0, 1) or 'balanced'")
        if not balanced:
            self.phase = _finite("phase", self.phase, 0.0, hi=1.0)
            if self.phase >= 1.0:
                raise WaveformError(f"phase: got {self.phase:g}, expected a share of a period in [0, 1)")
        self.knots()          # the ramps must fit in the period (raises naming slew_rate)
        if balanced:
            self.phase = 0.0
            self.phase = balanced_phase(self)

    @property
    def period(self) -> float:
        return 1.0 / self.frequency

    def transitions(self):
        """One period's switches: [(instant as a share of the period, from level, to level)]."""
        raise NotImplementedError

    def ramp_time(self, jump) -> float:
        """Duration (s) of a switch of `jump` volts: |jump| / slew_rate (0: ideal)."""
        return 0.0 if self.slew_rate is None else abs(jump) / self.slew_rate

    def knots(self):
        """(times, levels) of one period's polyline, from the first switch's ramp start
        (times may start below 0 and end above the period: ramps centred on an instant
        reach across it). Consecutive equal times are a jump. Raises WaveformError naming
        slew_rate when two ramps would overlap."""
        T = self.period
        tr = self.transitions()
        c = np.array([share * T for share, _, _ in tr])
        h = np.array([0.5 * self.ramp_time(b - a) for _, a, b in tr])
        gap = np.append(c[1:], c[0] + T) - c - np.append(h[1:], h[0]) - h
        if np.any(gap < -1e-12 * T):
            span = np.append(c[1:], c[0] + T) - c
            f_max = float(np.min(span * self.frequency / (h + np.append(h[1:], h[0]))))
            raise WaveformError(f"slew_rate: ramps of up to {2 * h.max():.4g} s (|jump| / {self.slew_rate:g} V/s) do "
                                f"not fit between the switches of {self.frequency:g} Hz at duty {self.duty:g}; expected a "
                                f"frequency <= {f_max:.4g} Hz or a faster slew rate")
        times = np.ravel(np.column_stack([c - h, c + h]))
        levels = np.ravel([[a, b] for _, a, b in tr]).astype(float)
        return times, levels

    def piecewise(self, duration):
        T = self.period
        tk, yk = self.knots()
        t0 = self.phase * T
        t1 = t0 + duration
        k0 = math.floor((t0 - tk[0]) / T)           # tiles of one period's knots covering [t0, t1]
        k1 = math.ceil((t1 - tk[-1]) / T) + 1
        check_segments("frequency", (k1 - k0) * len(tk),
                       f"{self.frequency:g} Hz over {duration:g} s; lower the frequency or shorten the run")
        k = np.arange(k0, k1)[:, None]
        t = (tk[None, :] + k * T).ravel()
        y = np.broadcast_to(yk, (len(k), len(yk))).ravel()
        # the polyline's pieces of positive length (a jump is two knots at one time)
        j = np.nonzero(t[1:] > t[:-1])[0]
        a, b = t[j], t[j + 1]
        eps = 1e-12 * max(t1, 1.0)
        keep = (b > t0 + eps) & (a < t1 - eps)
        j, a, b = j[keep], a[keep], b[keep]
        slope = (y[j + 1] - y[j]) / (b - a)
        start = np.maximum(a, t0)
        v0 = y[j] + slope * (start - a)
        return Piecewise(np.append(start, t1) - t0, v0, slope)


def balanced_phase(wave) -> float:
    """The phase (share of a period) at which g(t) = int_0^t (V - <V>) dt' first crosses
    its period mean (rising; falling for a negative amplitude): a drive started there has
    its interface charge oscillate about its period mean from the first period, instead
    of about an offset ~ V T / 4 that only leakage removes (tens of seconds). For ideal
    symmetric inversion that is T/4: half a pulse first. Exact (g is piecewise quadratic)."""
    from dataclasses import replace
    w0 = replace(wave, phase=0.0)
    t, v0, sl, g, vm, gm = _charge_profile(w0)
    sg = 1.0 if wave.V >= 0 else -1.0
    for i in range(len(v0)):
        # sg (g - <g>) on the segment: a + b s + c s^2 for s in [0, dt]
        a, b, c = sg * (g[i] - gm), sg * (v0[i] - vm), sg * 0.5 * sl[i]
        if a >= 0.0:
            return float(t[i] / w0.period) if i else 0.0
        roots = np.roots([c, b, a]) if c != 0.0 else (np.array([-a / b]) if b != 0.0 else np.array([]))
        roots = np.real(roots[np.abs(np.imag(roots)) <= 1e-12 * (abs(b) + abs(c) + 1e-300)])
        hit = roots[(roots >= 0.0) & (roots <= t[i + 1] - t[i])]
        if hit.size:
            return float(min((t[i] + hit.min()) / w0.period, np.nextafter(1.0, 0.0)))
    return 0.0


def charge_phase_offset(wave) -> float:
    """<g> - g(start) over one period from the drive's start (its phase), with g(t) =
    int (V - <V>) dt' (V s): a run from uncharged that starts there has its interface
    charge oscillate about b <g> (b: the charge's input gain) until leakage removes it;
    0 at the balanced phase."""
    return _charge_profile(wave)[5]


def period_means(wave) -> tuple[float, float, float]:
    """(<V>, <V^2>, g0) over one period of a periodic waveform from its start (its phase),
    exact for its piecewise-linear voltage; g0 = charge_phase_offset(wave)."""
    t, v0, sl, _, vm, gm = _charge_profile(wave)
    dt = np.diff(t)
    w = float(np.sum(v0 * v0 * dt + v0 * sl * dt * dt + sl * sl * dt ** 3 / 3.0) / (t[-1] - t[0]))
    return vm, w, gm


def _charge_profile(wave):
    """Over one period from the drive's start: breakpoints t, the segments' start values
    and slopes, g = int (V - <V>) at the breakpoints, <V>, and <g> (exact integrals of
    the piecewise-linear V)."""
    pw = wave.piecewise(wave.period)
    t, v0, sl = pw.t, pw.v0, pw.slope
    T = t[-1] - t[0]
    dt = np.diff(t)
    vm = float(np.sum(v0 * dt + 0.5 * sl * dt * dt) / T)
    g = np.concatenate([[0.0], np.cumsum((v0 - vm) * dt + 0.5 * sl * dt * dt)])
    gm = float(np.sum(g[:-1] * dt + 0.5 * (v0 - vm) * dt * dt + sl * dt ** 3 / 6.0) / T)
    return t, v0, sl, g, vm, gm


@dataclass
class Bipolar(_Periodic):
    """Polarity inversion: +V, -V square wave of `frequency` (full periods per second).

    duty          the share of each half period at full voltage (the paper's duty
                  cycle: 1.0 = 100 %, no dead time; the rest of each half is at 0 V).
                  One meaning everywhere: this class, `dfa simulate --duty`, the
                  protocol file, `dfa design` and the FMU drive.
    slew_rate     V/s: each switch a linear ramp centred on its ideal instant (an
                  inversion +V -> -V takes 2 V / slew_rate); None: ideal switching.
                  Where the 0 V gap between the two ramps of an inversion is shorter
                  than they need, the inversion is one ramp through 0 centred on the gap.
    phase         share of a period at which the drive starts, or "balanced"
                  (balanced_phase: the charge-balanced start).
    positive_share  share of each period given to the positive half (0.5: symmetric;
                  otherwise the drive has a mean of (2 positive_share - 1) duty V)."""

    V: float
    frequency: float
    duty: float = 1.0
    slew_rate: float | None = None
    phase: float | str = 0.0
    positive_share: float = 0.5

    def __post_init__(self):
        self.positive_share = _finite("positive_share", self.positive_share, 0.0, lo_incl=False, hi=1.0)
        if self.positive_share >= 1.0:
            raise WaveformError(f"positive_share: got {self.positive_share:g}, expected a value in (0, 1)")
        self._check_common()

    def transitions(self):
        V, d, P = self.V, self.duty, self.positive_share
        if d >= 1.0:
            return [(0.0, -V, V), (P, V, -V)]
        r = self.ramp_time(V)        # a switch between 0 and +-V
        e = P + d * (1.0 - P)        # end of the negative pulse
        tr = []
        # a 0 V gap shorter than its two half ramps: one inversion through 0, centred on the gap
        if (1.0 - d) * (1.0 - P) * self.period < r:
            tr.append((0.5 * (e + 1.0) - 1.0, -V, V))
        else:
            tr += [(0.0, 0.0, V), (e, -V, 0.0)]
        if (1.0 - d) * P * self.period < r:
            tr.append((0.5 * (d * P + P), V, -V))
        else:
            tr += [(d * P, V, 0.0), (P, 0.0, -V)]
        return sorted(tr)


@dataclass
class Unipolar(_Periodic):
    """Unipolar pulse train: V for `duty` of each period, then 0 V (`slew_rate`,
    `phase`: as for Bipolar)."""

    V: float
    frequency: float
    duty: float = 0.5
    slew_rate: float | None = None
    phase: float | str = 0.0

    def __post_init__(self):
        self._check_common()

    def transitions(self):
        if self.duty >= 1.0:
            return [(0.0, self.V, self.V)]      # always on
        return [(0.0, 0.0, self.V), (self.duty, self.V, 0.0)]


@dataclass
class Sampled(Waveform):
    """A sampled signal: linear interpolation between samples (`hold=False`) or
    zero-order hold (`hold=True`). Held constant after the last sample."""

    times: np.ndarray
    values: np.ndarray
    hold: bool = False
    name: str = "voltage"

    def __post_init__(self):
        self.times = np.asarray(self.times, float).ravel()
        self.values = np.asarray(self.values, float).ravel()
        if self.times.size == 0 or self.times.size != self.values.size:
            raise WaveformError(f"{self.name}: times and values must be non-empty and of equal length "
                                f"(got {self.times.size} and {self.values.size})")
        if not (np.all(np.isfinite(self.times)) and np.all(np.isfinite(self.values))):
            bad = int(np.nonzero(~(np.isfinite(self.times) & np.isfinite(self.values)))[0][0])
            raise WaveformError(f"{self.name}: samples must be finite numbers (sample {bad}: time "
                                f"{self.times[bad]!r}, value {self.values[bad]!r})")
        bound, unit = SIGNALS.get(self.name, (np.inf, ""))
        if np.any(np.abs(self.values) > bound):
            bad = int(np.argmax(np.abs(self.values)))
            raise WaveformError(f"{self.name}: sample {bad} is {self.values[bad]:g} {unit}, expected a magnitude "
                                f"<= {bound:g} {unit}")
        check_segments(self.name, self.times.size)
        if np.any(np.diff(self.times) < 0):
            raise WaveformError(f"{self.name}: sample times must be non-decreasing")
        if self.times[0] > 0:
            raise WaveformError(f"{self.name}: first sample time must be <= 0 s (got {self.times[0]:g})")

    @property
    def amplitude(self):
        return float(np.max(np.abs(self.values)))

    def piecewise(self, duration):
        t, v = self.times, self.values
        # strictly increasing breakpoints; a repeated time is a jump (the later sample wins)
        tb = [0.0]
        v0 = []
        sl = []
        for i in range(len(t)):
            t_next = t[i + 1] if i + 1 < len(t) else np.inf
            if t_next <= 0 or t_next == t[i]:
                continue
            a = max(t[i], 0.0)
            b = min(t_next, duration)
            if b <= a:
                if a >= duration:
                    break
                continue
            if self.hold or not np.isfinite(t_next):
                s, va = 0.0, v[i]
            else:
                s = (v[i + 1] - v[i]) / (t_next - t[i])
                va = v[i] + s * (a - t[i])
            if tb[-1] != a:
                tb.append(a)
            v0.append(va)
            sl.append(s)
            tb.append(b)
            if b >= duration:
                break
        tb = np.array(tb)
        # consecutive duplicates produced by the loop
        _, idx = np.unique(tb, return_index=True)
        tb = tb[np.sort(idx)]
        return Piecewise(tb, np.array(v0), np.array(sl))


def from_function(fn, duration, dt=1e-3, name="voltage") -> Sampled:
    """Sample a user callable V(t) every dt on [0, duration] (linear in between)."""
    dt = _finite(f"{name} dt", dt, 0.0, lo_incl=False)
    duration = _finite("duration", duration, 0.0, lo_incl=False, hi=MAX_DURATION)
    check_segments(f"{name} dt", duration / dt, f"sampling every {dt:g} s over {duration:g} s; use a larger dt")
    n = int(math.ceil(duration / dt)) + 1
    t = np.linspace(0.0, duration, n)
    try:
        v = np.array([float(fn(ti)) for ti in t])
    except Exception as exc:  # the user's code failed: say where
        raise WaveformError(f"{name}: the callable raised {type(exc).__name__}: {exc}") from None
    return Sampled(t, v, name=name)


@dataclass
class Stage:
    waveform: Waveform
    duration: float
    label: str = ""


@dataclass
class Protocol:
    """Stages applied one after the other, time 0 at the start of the first; `load`
    (optional): the load that goes with the drive (a protocol file's [load]), used by
    simulate when no load is given there.

    Protocol files (README, 'Protocol file'): Protocol.from_toml(text or path),
    protocol.to_toml(), protocol.save(path)."""

    stages: list = field(default_factory=list)
    load: Load | None = None

    def __post_init__(self):
        if not self.stages:
            raise WaveformError("protocol: needs at least one stage")
        if self.load is not None and not isinstance(self.load, Load):
            self.load = Load(self.load)
        for s in self.stages:
            s.duration = _finite(f"duration of stage {s.label or '?'}", s.duration, 0.0, lo_incl=False,
                                 hi=MAX_DURATION)
        if self.duration > MAX_DURATION:
            raise WaveformError(f"duration: the stages add up to {self.duration:g} s, expected <= {MAX_DURATION:g} s")

    @property
    def duration(self):
        return sum(s.duration for s in self.stages)

    @property
    def boundaries(self):
        return np.concatenate([[0.0], np.cumsum([s.duration for s in self.stages])])

    def stage_span(self, label):
        # the running sum is `boundaries` (np.cumsum adds in order), without its arrays:
        # every result's metrics ask for spans
        t = 0.0
        for s in self.stages:
            if s.label == label:
                return t, t + s.duration
            t += s.duration
        return None

    @property
    def amplitude(self):
        return max(s.waveform.amplitude for s in self.stages)

    def piecewise(self) -> Piecewise:
        b = self.boundaries
        return Piecewise.concat([s.waveform.piecewise(s.duration).shifted(b[i]) for i, s in enumerate(self.stages)])

    def voltage(self, t):
        return self.piecewise()(t)

    # protocol files (dfa_model.io.protocol_file, which registers itself: FILE_FORMAT) --
    def to_toml(self, header=None) -> str:
        """The protocol-file text (every number exact; `header`: comment lines first)."""
        return _file_format().to_toml(self, header)

    def save(self, path, header=None) -> list:
        """Write a protocol file (long sampled signals go to CSVs beside it); returns the
        paths written."""
        return _file_format().save(self, path, header)

    @classmethod
    def from_toml(cls, source, folder=None) -> "Protocol":
        """A protocol from a protocol file: `source` is a path (str or Path) to one, or
        its TOML text (sampled signals' files then relative to `folder`, default the
        current folder)."""
        import os

        protocol_file = _file_format()
        if isinstance(source, os.PathLike) or (isinstance(source, str) and "\n" not in source
                                               and "[[stage]]" not in source):
            return protocol_file.load(source)
        return protocol_file.from_toml(source, folder)

    # constructors --------------------------------------------------------------
    @classmethod
    def dc(cls, V, duration):
        return cls([Stage(DC(V), duration, "hold")])

    @classmethod
    def reset_then_hold(cls, V, hold, reset=3.0, reset_frequency=30.0, hold_waveform=None):
        """The paper's routine (Sec. 4.2): a bipolar 100 % duty square wave at the test
        amplitude for `reset` s, then `hold_waveform` (default DC at V) for `hold` s."""
        return cls([Stage(Bipolar(V, reset_frequency, 1.0), reset, "reset"),
                    Stage(hold_waveform or DC(V), hold, "hold")])

    @classmethod
    def single(cls, waveform, duration, label="hold"):
        return cls([Stage(waveform, duration, label)])


@dataclass
class Load:
    """External force opposing zipping: F(t) (constant, sampled or callable) plus a
    linear spring k_load x."""

    F: object = 0.0
    k_load: float = 0.0
    dt: float = 1e-3

    def __post_init__(self):
        self.k_load = _finite("k_load", self.k_load, 0.0, hi=1e9)
        if isinstance(self.F, Sampled) and self.F.name != "force":
            self.F = Sampled(self.F.times, self.F.values, self.F.hold, name="force")
        elif not (callable(self.F) or isinstance(self.F, Sampled)):
            self.F = _level("force", self.F)

    def piecewise(self, duration) -> Piecewise:
        if isinstance(self.F, Sampled):
            return self.F.piecewise(duration)
        if callable(self.F):
            return from_function(self.F, duration, self.dt, name="force").piecewise(duration)
        return DC(self.F).piecewise(duration)

    @property
    def F0(self) -> float:
        return float(self.piecewise(1.0).v0[0])


def build_protocol(voltage, duration, waveform="dc", frequency=None, duty=None, reset=0.0,
                   reset_frequency=None) -> Protocol:
    """The CLI's protocol: optional charge reset (bipolar, 100 % duty, at `voltage`,
    `reset_frequency` Hz, default 30), then `duration` s of `waveform` ('dc', 'bipolar'
    or 'unipolar'). A setting that would have no effect (a frequency or duty on a DC
    hold, a reset frequency without a reset) is an error."""
    if duration is None:
        raise WaveformError("duration: required (seconds of the hold stage, after any reset)")
    if voltage is None:
        raise WaveformError("voltage: required (amplitude, V)")
    if waveform == "dc":
        for name, value in (("frequency", frequency), ("duty", duty)):
            if value is not None:
                raise WaveformError(f"--{name}: does not apply to --waveform dc (use bipolar or unipolar)")
        wf = DC(voltage)
    elif waveform in ("bipolar", "unipolar"):
        if frequency is None:
            raise WaveformError(f"--frequency: required with waveform {waveform}")
        if duty is None:
            duty = 1.0 if waveform == "bipolar" else 0.5
        wf = (Bipolar if waveform == "bipolar" else Unipolar)(voltage, frequency, duty)
    else:
        raise WaveformError(f"waveform: got {waveform!r}, expected 'dc', 'bipolar' or 'unipolar'")
    stages = []
    reset = _finite("reset", reset or 0.0, 0.0, hi=MAX_DURATION)
    if reset_frequency is not None and reset == 0:
        raise WaveformError("--reset-frequency: applies only with --reset SECONDS > 0")
    if reset:
        reset_frequency = _finite("reset_frequency", 30.0 if reset_frequency is None else reset_frequency, 0.0,
                                  lo_incl=False, hi=1e6)
        stages.append(Stage(Bipolar(voltage, reset_frequency, 1.0), reset, "reset"))
    stages.append(Stage(wf, duration, "hold"))
    return Protocol(stages)


# The kernels' input segments of recent protocols (segments()): building them costs about
# a tenth of a full-model run of the standard protocol and as much as half a surrogate
# run, and a process that runs one protocol on several models (dfa compare, sweeps,
# fits) builds them once.
_PURE_WAVEFORMS = (DC, Bipolar, Unipolar)   # segments a function of their fields and the stage duration
SEGMENT_CACHE_MAX = 20_000                  # largest protocol (segments) whose inputs are kept
_SEGMENTS: dict = {}


def segment_key(protocol: Protocol, load: Load):
    """Every field (name and value) a protocol's and load's input segments depend on, as a
    tuple, or None when they are not only fields (a user waveform, a sampled or callable
    load) or a value is not hashable. A tuple, not their text: repr took 2.3 us of a
    surrogate run's 170 (every run asks), the tuple 0.7."""
    if type(protocol) is Protocol and type(load) is Load and type(load.F) is float and \
            all(type(st.waveform) in _PURE_WAVEFORMS for st in protocol.stages):
        key = (load.F, tuple((type(st.waveform), tuple(vars(st.waveform).items()), st.duration)
                             for st in protocol.stages))
        try:
            hash(key)
        except TypeError:
            return None
        return key
    return None


def segments(protocol: Protocol, load: Load):
    """merge(protocol.piecewise(), load.piecewise(duration)): (t, V0, Vs, F0, Fs), the
    kernels' input segments. Those of recent protocols are kept, keyed on the text of
    every field they depend on (a mutated protocol gets a new key): only for the stock
    waveforms, a constant load and at most SEGMENT_CACHE_MAX segments. The arrays are
    shared: the kernels only read them, and so must callers."""
    key = segment_key(protocol, load)
    if key is not None:
        seg = _SEGMENTS.get(key)
        if seg is not None:
            return seg
    seg = merge(protocol.piecewise(), load.piecewise(protocol.duration))
    if key is not None and len(seg[1]) <= SEGMENT_CACHE_MAX:
        if len(_SEGMENTS) >= 16:
            _SEGMENTS.clear()
        _SEGMENTS[key] = seg
    return seg
