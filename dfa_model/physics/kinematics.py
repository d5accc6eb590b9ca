"""V-shaped and Peano-HASEL geometry: x -> l_z, theta, t_l(s, x), dt_l/dx.

The compiled kernels below are the single implementation; the classes wrap them for
Python use (statics, plots, tests). Geometry is packed in a float array `geo`:

    v-shaped:    [l, a, l_e, w, L = sqrt(l^2 - a^2), x_e, 0, 0]
    peano-hasel: [l, A = volume/w, l_e, w, a_0, x_e, theta_0, theta_e]

where x_e is the stroke at which the front reaches the electrode end. `kin_eval`
fills `kin = [l_z, D, p1, p2, p3, p4]`, D being the lever dp/dx of the profile
parameter p (p = l_z for v-shaped, p = theta for peano-hasel).

Peano-HASEL, Eq. (23): the liquid cross-section of Eq. (22) is two circular segments
of chord 2 R sin(theta). The paper's second line of Eq. (23) writes (a_0 - l_z) for
that chord, which holds only at x = 0; we use the chord 2 R sin(theta), so that
with R = (l - l_z)/(2 theta) the area equation reads
    (theta - sin theta cos theta) / theta^2 = 2 A / (l - l_z)^2,
monotonic in theta on (0, pi/2]. theta parametrises the whole motion explicitly.
"""
from __future__ import annotations

import math

import numpy as np
from .._jit import njit

V_SHAPED, PEANO = 0, 1
HALF_PI = 0.5 * math.pi


# ---------------------------------------------------------------- peano helpers
@njit(cache=True, _nrt=False)
def _pf(theta):
    """f(theta) = (theta - sin cos)/theta^2 and its derivative."""
    s, c = math.sin(theta), math.cos(theta)
    # theta - s c = theta - sin(2 theta)/2 loses digits for small theta: use the series
    if theta < 1e-2:
        t2 = theta * theta
        num = theta * t2 * (2.0 / 3.0 - t2 * (2.0 / 15.0 - t2 * 4.0 / 315.0))
    else:
        num = theta - s * c
    f = num / (theta * theta)
    fp = 2.0 * c * (s - theta * c) / (theta * theta * theta)
    return f, fp


@njit(cache=True, _nrt=False)
def peano_state(theta, l, A):
    """(l_z, R, x + l - a_0 (i.e. without a_0), dx/dtheta, P', R') at half-angle theta."""
    f, fp = _pf(theta)
    P = math.sqrt(2.0 * A / f)            # l - l_z, the bulged length
    Pp = -0.5 * P * fp / f
    s, c = math.sin(theta), math.cos(theta)
    sinc = s / theta
    R = P / (2.0 * theta)
    Rp = Pp / (2.0 * theta) - P / (2.0 * theta * theta)
    x_rel = P * (1.0 - sinc) - l           # x = a_0 + x_rel
    dxdt = Pp * (1.0 - sinc) + P * (s - theta * c) / (theta * theta)
    return l - P, R, x_rel, dxdt, Pp, Rp


@njit(cache=True, _nrt=False)
def peano_theta_of_lz(lz, l, A):
    """theta in (0, pi/2] with (theta - s c)/theta^2 = 2A/(l - lz)^2 (bisection+Newton)."""
    g = 2.0 * A / ((l - lz) * (l - lz))
    lo, hi = 1e-9, HALF_PI
    th = min(max(1.5 * g, 1e-6), HALF_PI)   # f ~ 2 theta/3 for small theta
    for _ in range(100):
        f, fp = _pf(th)
        r = f - g
        if r > 0.0:
            hi = th
        else:
            lo = th
        step = r / fp if fp > 0.0 else 0.0
        nt = th - step
        if not (lo < nt < hi):
            nt = 0.5 * (lo + hi)
        if abs(nt - th) <= 1e-15 * max(1.0, th):
            th = nt
            break
        th = nt
    return th


@njit(cache=True, _nrt=False)
def kin_eval(layout, geo, x, kin):
    """Fill kin = [l_z, D, p1..p4] at stroke x (clamped to [0, x_e])."""
    x_e = geo[5]
    xx = min(max(x, 0.0), x_e)
    if layout == V_SHAPED:
        l, a, L = geo[0], geo[1], geo[4]
        den = 2.0 * (l + xx - L)
        num = 2.0 * xx * L - xx * xx
        lz = num / den
        D = ((2.0 * L - 2.0 * xx) * den - 2.0 * num) / (den * den)
        kin[0] = lz
        kin[1] = D
        kin[2] = 2.0 * a / (l - lz)          # slope of the gap, dt_l/ds
        kin[3] = l - lz
        kin[4] = kin[2] / kin[3]
        kin[5] = 0.0
    else:
        l, A, a0, th0, the = geo[0], geo[1], geo[4], geo[6], geo[7]
        target = xx - a0
        lo, hi = th0, the
        th = th0 + (the - th0) * (xx / x_e) if x_e > 0 else th0
        for _ in range(100):
            lz, R, xr, dxdt, Pp, Rp = peano_state(th, l, A)
            r = xr - target
            if r > 0.0:
                hi = th
            else:
                lo = th
            nt = th - r / dxdt if dxdt > 0.0 else 0.5 * (lo + hi)
            if not (lo <= nt <= hi):
                nt = 0.5 * (lo + hi)
            if abs(nt - th) <= 1e-15:
                th = nt
                break
            th = nt
        lz, R, xr, dxdt, Pp, Rp = peano_state(th, l, A)
        kin[0] = lz
        kin[1] = 1.0 / dxdt
        kin[2] = th
        kin[3] = R
        kin[4] = Rp
        kin[5] = -Pp                          # dl_z/dtheta


@njit(cache=True, _nrt=False, inline='always')
def profile(layout, geo, kin, sigma):
    """Gap beyond the front at distance sigma = s - l_z: (t_l - t_lz, dt_l/dp at fixed s)."""
    if layout == V_SHAPED:
        k = kin[2]
        return k * sigma, -k + sigma * kin[4]       # kin[4] = k / (l - l_z)
    th, R, Rp, lzp = kin[2], kin[3], kin[4], kin[5]
    phi = th - sigma / R
    cphi, cth = math.cos(phi), math.cos(th)
    dphi = 1.0 + lzp / R + sigma * Rp / (R * R)
    gap = 2.0 * R * (cphi - cth)
    dgap = 2.0 * Rp * (cphi - cth) + 2.0 * R * (math.sin(th) - math.sin(phi) * dphi)
    return gap, dgap


@njit(cache=True, _nrt=False, inline='always')
def front_slope(layout, kin):
    """dt_l/ds just beyond the front."""
    if layout == V_SHAPED:
        return kin[2]
    return 2.0 * math.sin(kin[2])


@njit(cache=True, _nrt=False)
def zipping_angle(layout, geo, kin):
    """Eq. (18) for v-shaped; the half curvature angle theta for peano-hasel (rad)."""
    if layout == V_SHAPED:
        return 2.0 * math.asin(min(1.0, geo[1] / kin[3]))
    return kin[2]


# ---------------------------------------------------------------- python API
def peano_lz_max(l: float, A: float) -> float:
    """Zipped length at which the bulge becomes a full circle (theta = pi/2)."""
    return l - math.sqrt(math.pi * A)


def _brent(fun, lo, hi):
    from scipy.optimize import brentq
    return brentq(fun, lo, hi, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200)


class Kinematics:
    """Geometry of one actuator: stroke <-> zipped length, angle, liquid gap."""

    layout_id: int

    def __init__(self, p):
        self.p = p
        self.geo = np.zeros(8)
        self._kin = np.zeros(6)

    def state(self, x: float) -> np.ndarray:
        kin_eval(self.layout_id, self.geo, float(x), self._kin)
        return self._kin.copy()

    def lz(self, x):
        """Zipped length l_z(x) (m); vectorised."""
        return np.vectorize(lambda xx: self.state(xx)[0])(x)

    def dlz_dx(self, x):
        return np.vectorize(lambda xx: self._dlz_dx(self.state(xx)))(x)

    def angle(self, x):
        """Zipping angle (rad), Eq. (18) or the Peano half curvature angle."""
        return np.vectorize(lambda xx: zipping_angle(self.layout_id, self.geo, self.state(xx)))(x)

    def t_l(self, s, x):
        """Liquid thickness t_l(s, x) (m), Eqs. (19)/(24)."""
        kin = self.state(x)
        s = np.asarray(s, float)
        sig = s - kin[0]
        gap = np.array([profile(self.layout_id, self.geo, kin, v)[0] if v > 0 else 0.0 for v in np.ravel(sig)])
        return self.p.t_lz + gap.reshape(s.shape)

    def dt_l_dx(self, s, x):
        """Partial derivative of t_l(s, x) with respect to x at fixed s."""
        kin = self.state(x)
        s = np.asarray(s, float)
        sig = s - kin[0]
        d = np.array([profile(self.layout_id, self.geo, kin, v)[1] if v > 0 else 0.0 for v in np.ravel(sig)])
        return (d * kin[1]).reshape(s.shape)

    @property
    def x_e(self) -> float:
        """Stroke at which the zipping front reaches the electrode end."""
        return self.geo[5]


class VShaped(Kinematics):
    layout_id = V_SHAPED

    def __init__(self, p):
        super().__init__(p)
        L = math.sqrt(p.l ** 2 - p.a ** 2)
        self.geo[:5] = [p.l, p.a, p.l_e, p.w, L]
        self.geo[5] = self.x_of_lz(p.l_e)
        self.theta0 = 2.0 * math.asin(p.a / p.l)

    def x_of_lz(self, lz):
        """Eq. (16)."""
        p = self.p
        return math.sqrt(p.l ** 2 - p.a ** 2) - lz - math.sqrt((p.l - lz) ** 2 - p.a ** 2)

    @staticmethod
    def _dlz_dx(kin):
        return kin[1]


class PeanoHasel(Kinematics):
    layout_id = PEANO

    def __init__(self, p):
        super().__init__(p)
        A = p.volume / p.w
        th0 = peano_theta_of_lz(0.0, p.l, A)
        R0 = p.l / (2.0 * th0)
        a0 = 2.0 * R0 * math.sin(th0)
        the = peano_theta_of_lz(p.l_e, p.l, A)
        self.geo[:8] = [p.l, A, p.l_e, p.w, a0, 0.0, th0, the]
        self.geo[5] = a0 + peano_state(the, p.l, A)[2]
        self.theta0, self.R0, self.a0, self.A = th0, R0, a0, A

    def x_of_lz(self, lz):
        th = peano_theta_of_lz(lz, self.p.l, self.A)
        return self.a0 + peano_state(th, self.p.l, self.A)[2]

    @staticmethod
    def _dlz_dx(kin):
        return kin[5] * kin[1]

    def x_of_lz_paper(self, lz):
        """Stroke from Eq. (23) exactly as printed (chord written as a_0 - l_z), for
        comparison only. Returns NaN where it has no root in (0, pi/2]."""
        l, A, a0 = self.p.l, self.A, self.a0

        def area_res(th):
            R = (l - lz) / (2 * th)
            return A - 2 * th * R * R + (a0 - lz) * R * math.cos(th)

        # the root on the branch through theta_0 (nearest the chord-correct angle)
        th_ref = peano_theta_of_lz(lz, l, A)
        grid = np.linspace(1e-4, HALF_PI, 4000)
        vals = [area_res(t) for t in grid]
        roots = [_brent(area_res, grid[i], grid[i + 1]) for i in range(len(grid) - 1)
                 if vals[i] == 0 or vals[i] * vals[i + 1] < 0]
        if not roots:
            return float("nan")
        th = min(roots, key=lambda r: abs(r - th_ref))
        R = (l - lz) / (2 * th)
        return a0 - lz - 2 * R * math.sin(th)


def make(p) -> Kinematics:
    return VShaped(p) if p.layout == "v-shaped" else PeanoHasel(p)
