"""A signal x(t) as the solver computed it: piecewise quadratic over its accepted steps.

The integrator records, for every accepted step [t_i, t_i+1], the stroke at the step's
start, at its stage t_i + gamma h and at its end; the quadratic through the three is the
solver's own dense output (the one `t_eval` samples). Metrics computed from it do not
depend on how the user samples the output (`--dt 2` once reported a static stroke of
0.214 mm for 0.865 mm; a 1 ms output sampled a 30 Hz ripple 15x too low).

A sampled recording is the same object with linear pieces (`StrokeTrace.from_samples`),
so measured and simulated records share one set of metrics. Window queries (value,
mean, minimum, maximum over many windows) take O(pieces + windows) time.
"""
from __future__ import annotations

import math
from functools import cached_property

import numpy as np

GAMMA = 2.0 - math.sqrt(2.0)     # TR-BDF2's stage fraction (integrator.GAMMA)
# a peak is where x first comes within this share of its maximum: far below the solver's
# resolution (rtol 1e-4), far above a held stroke's round-off creep
PEAK_RTOL = 1e-6
_NONE = np.empty(0)
_NONE.flags.writeable = False


class StrokeTrace:
    """x(t) on [t[0], t[-1]]: on piece i, s = (t - t[i]) / h[i] in [0, 1] and
    x = c0[i] + c1[i] s + c2[i] s^2. Values are clipped to [lo, hi] (the stroke's stops:
    the quadratic through three values inside them may overshoot in between)."""

    def __init__(self, t, x_start, x_stage, x_end, gamma=GAMMA, lo=-np.inf, hi=np.inf):
        t = np.asarray(t, float)
        x_start, x_stage, x_end = (np.asarray(v, float) for v in (x_start, x_stage, x_end))
        keep = self._knots(t, x_start.size)
        a, g, b = np.array(x_start[keep]), x_stage[keep], x_end[keep]   # c0 a copy (keep may be a slice)
        self.c2 = ((g - a) - gamma * (b - a)) / (gamma * gamma - gamma)
        self.c1 = b - a - self.c2
        self.c0 = a
        self.lo, self.hi = lo, hi
        self.x_last = float(x_end[-1]) if x_end.size else float("nan")
        # the window queries' tables (_cum, _kx, _vertices) are built on first use: most
        # results are asked for a value or two (unzipping speed, final stroke) only

    def _knots(self, t, pieces):
        """Check the times, keep the pieces of non-zero length (zero-length pieces carry
        no time): sets t and h, returns the mask of kept pieces."""
        if t.ndim != 1 or t.size < 1 or pieces != t.size - 1:
            raise ValueError("StrokeTrace: need n + 1 times and n pieces")
        h = t[1:] - t[:-1]
        # finite and non-decreasing: finite ends and no step below 0 (a NaN or an inf
        # inside makes a step NaN or negative); one reduction instead of three arrays
        h_min = h.min() if h.size else 0.0
        if not (h_min >= 0.0 and math.isfinite(t[0]) and math.isfinite(t[-1])):
            raise ValueError("StrokeTrace: times must be finite and non-decreasing")
        if h_min > 0.0:
            self.t, self.h = t, h
            return slice(None)       # every piece: views, not copies
        keep = h > 0
        self.t, self.h = np.concatenate([t[:1], t[1:][keep]]), h[keep]
        return keep

    @cached_property
    def _cum(self):
        """Integral from t[0] to each knot."""
        return np.concatenate([[0.0], np.cumsum(self.h * (self.c0 + self.c1 / 2 + self.c2 / 3))])

    @cached_property
    def _kx(self):
        """Knot values (piece starts, then the end), for extrema."""
        return _clip(np.append(self.c0, self.c0[-1] + self.c1[-1] + self.c2[-1]) if self.h.size
                     else np.array([self.x_last]), self.lo, self.hi)

    @cached_property
    def _vertices(self):
        """(times, values) of the pieces' interior vertices, for extrema."""
        with np.errstate(divide="ignore", invalid="ignore"):
            sv = -self.c1 / (2.0 * self.c2)
        inside = (sv > 0) & (sv < 1)          # c2 = 0 gives inf or nan here: never inside
        vt = self.t[:-1][inside] + sv[inside] * self.h[inside]
        sv = sv[inside]
        return vt, _clip(self.c0[inside] + sv * (self.c1[inside] + sv * self.c2[inside]), self.lo, self.hi)

    @property
    def _vt(self):
        return self._vertices[0]

    @property
    def _vx(self):
        return self._vertices[1]

    # ------------------------------------------------------------------ constructors
    @classmethod
    def from_solver(cls, rows, lo=0.0, hi=np.inf):
        """From the integrator's trace rows: (t0, x0, x0), then (t_end, x_stage, x_end)
        per accepted step."""
        rows = np.asarray(rows, float)
        return cls(rows[:, 0], rows[:-1, 2], rows[1:, 1], rows[1:, 2], lo=lo, hi=hi)

    @classmethod
    def from_samples(cls, t, x):
        """Linear interpolation between samples (a recording, or a solver output)."""
        t = np.asarray(t, float)
        x = np.asarray(x, float)
        if t.shape != x.shape or t.ndim != 1 or t.size == 0:
            raise ValueError("StrokeTrace.from_samples: t and x must be 1-d arrays of equal, non-zero length")
        self = cls.__new__(cls)
        keep = self._knots(t, t.size - 1)
        # the linear pieces directly (a quadratic through a point on the line gave c2 at
        # round-off, not 0)
        a, b = np.array(x[:-1][keep]), x[1:][keep]     # c0 a copy: not a view of the caller's samples
        self.c0, self.c1, self.c2 = a, b - a, np.zeros(a.size)
        self.lo, self.hi = -np.inf, np.inf
        self.__dict__["_vertices"] = (_NONE, _NONE)   # linear pieces: no interior vertices
        self.x_last = float(x[-1])
        return self

    # ------------------------------------------------------------------ queries
    @property
    def t0(self) -> float:
        return float(self.t[0])

    @property
    def t1(self) -> float:
        return float(self.t[-1])

    def _locate(self, tq):
        """Piece index and fraction s for times tq (clamped into the trace's span)."""
        tq = _clip(np.asarray(tq, float), self.t[0], self.t[-1])
        i = np.clip(np.searchsorted(self.t, tq, side="right") - 1, 0, max(self.h.size - 1, 0))
        if self.h.size == 0:
            return tq, i, np.zeros_like(tq)
        return tq, i, (tq - self.t[i]) / self.h[i]

    def __call__(self, tq):
        """x at times tq (held at the end values outside the span)."""
        if isinstance(tq, float) and self.h.size:
            return self._at(tq)
        tq, i, s = self._locate(tq)
        if self.h.size == 0:
            return np.full(np.shape(tq), self.x_last)
        return _clip(self.c0[i] + s * (self.c1[i] + s * self.c2[i]), self.lo, self.hi)

    def _at(self, tq: float):
        """x at one time: __call__'s arithmetic on scalars, without its array overhead
        (the metrics' common case)."""
        t = self.t
        tq = min(max(tq, t[0]), t[-1])
        i = min(max(int(t.searchsorted(tq, side="right")) - 1, 0), self.h.size - 1)
        s = (tq - t[i]) / self.h[i]
        return np.float64(min(max(self.c0[i] + s * (self.c1[i] + s * self.c2[i]), self.lo), self.hi))

    def _primitive(self, tq):
        tq, i, s = self._locate(tq)
        if self.h.size == 0:
            return np.zeros(np.shape(tq))
        return self._cum[i] + self.h[i] * s * (self.c0[i] + s * (self.c1[i] / 2 + s * self.c2[i] / 3))

    def integral(self, a, b):
        """Integral of x over [a, b] (vectorised over windows)."""
        return self._primitive(b) - self._primitive(a)

    def mean(self, a, b):
        """Time mean of x over [a, b]; x(a) where the window is empty. Within the window's
        extrema: the difference of the primitive rounds, and a stroke resting on its stop
        must not average to a hair beyond it."""
        a = np.asarray(a, float)
        b = np.asarray(b, float)
        width = b - a
        with np.errstate(invalid="ignore", divide="ignore"):
            m = self.integral(a, b) / width
        lo, hi = self.extrema(a, b)
        return np.where(width > 0, np.clip(m, lo.reshape(m.shape), hi.reshape(m.shape)), self(a))

    def extrema(self, a, b):
        """(min, max) of x over each window [a, b] (vectorised)."""
        a = np.atleast_1d(np.asarray(a, float))
        b = np.atleast_1d(np.asarray(b, float))
        ends = np.stack([self(a), self(b)])
        lo = np.minimum(np.min(ends, axis=0), np.minimum(_reduce(self.t, self._kx, a, b, np.minimum, np.inf),
                                                         _reduce(self._vt, self._vx, a, b, np.minimum, np.inf)))
        hi = np.maximum(np.max(ends, axis=0), np.maximum(_reduce(self.t, self._kx, a, b, np.maximum, -np.inf),
                                                         _reduce(self._vt, self._vx, a, b, np.maximum, -np.inf)))
        return lo, hi

    def max(self) -> float:
        """Largest value over the whole trace."""
        return float(max(self._kx.max(), self._vx.max(initial=-np.inf)))

    def min(self) -> float:
        """Smallest value over the whole trace."""
        return float(min(self._kx.min(), self._vx.min(initial=np.inf)))

    def argmax(self, a=None, b=None, rtol=PEAK_RTOL) -> float:
        """Time of the peak of x over [a, b]: the first time x comes within rtol |max| of
        its largest value. On a plateau that is where the plateau starts: a stroke held
        on a stop, or stuck at a force jump of the paper scheme, creeps by ~1e-12 m, and
        the time of its last-digit maximum is arbitrary (it moved the paper scheme's
        unzipping speed at N = 3001 from 20 to 32 um/s)."""
        if a is None and b is None and self.h.size:
            return self._argmax_all(rtol)
        a = self.t0 if a is None else float(a)
        b = self.t1 if b is None else float(b)
        cand_t = np.concatenate([[a, b], self.t[(self.t >= a) & (self.t <= b)],
                                 self._vt[(self._vt >= a) & (self._vt <= b)]])
        vals = self(cand_t)
        best = np.max(vals)
        return float(np.min(cand_t[vals >= best - rtol * abs(best)]))

    def _argmax_all(self, rtol):
        """argmax over the whole span, the same candidates and values without the windows'
        masks (the unzipping speed asks for it on every result: 17 of its 20 us): the knots'
        values (the last one as __call__ computes it, at s = 1) and the vertices'."""
        kv = _clip(np.append(self.c0, self.c0[-1] + (self.c1[-1] + self.c2[-1])), self.lo, self.hi)
        vt = self._vt
        vv = self(vt) if vt.size else vt
        best = max(kv.max(), vv.max(initial=-np.inf))
        thr = best - rtol * abs(best)
        ok = kv >= thr
        i = int(np.argmax(ok))                 # the first knot there (0 when none is)
        return float(min(self.t[i] if ok[i] else np.inf, vt[vv >= thr].min(initial=np.inf)))


def _clip(x, lo, hi):
    """np.clip without its wrapper's overhead (this runs on every result)."""
    return np.minimum(np.maximum(x, lo), hi)


def _reduce(times, vals, a, b, ufunc, empty):
    """ufunc-reduction of vals over the sorted times inside each window [a, b]; `empty`
    where a window holds none. One reduceat over interleaved bounds: O(n + windows)."""
    i0 = np.searchsorted(times, a, side="left")
    i1 = np.searchsorted(times, b, side="right")
    out = np.full(a.shape, empty)
    ok = i1 > i0
    if not np.any(ok):
        return out
    ext = np.append(vals, empty)           # index len(vals) must be valid for reduceat
    idx = np.column_stack([i0[ok], i1[ok]]).ravel()
    out[ok] = ufunc.reduceat(ext, idx)[::2]
    return out
