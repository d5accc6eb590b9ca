"""The surrogates' fast simulation path: one compiled integrator for every family.

Every surrogate has the same shape (see surrogate.py): an interface charge z1 with
linear dynamics at each stroke, an optional front-layer deficit z2, a force quadratic in
(V, z1 - z2) and 1-DOF mechanics. Its maps of the stroke are tabulated on a uniform
grid over [0, x_e] and interpolated linearly.

The state handed to the integrator is y = [x, v, z1, z2, V, F]: the inputs ride along as
states with constant slopes on each input segment, so ramps (a finite slew rate) stay
exact and the system is autonomous. Steps are the Rosenbrock-W pair of Shampine's
ode23s (L-stable, order 2, error estimated at order 3),
restarted at every input breakpoint (the switches are events); the stops at 0 and x_e
are located as events too. The Jacobian is by forward differences.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

# table columns (per grid point)
# (W_F: the front layer's width w_f)
C0, C1, C2, A_Q, B_V, I0, I1, J0, J1, DLZ, A_F, B_F, W_F = range(13)
NTAB = 13
# parameters (P_FRONT: 1.0 when the front layer differs from zipped material: q_d is a state;
# P_CELL: the renewal length over the layer's width, ell = c_ell w_f; P_BETA: the share of
# the layer's own deficit carried by the material beyond the front)
P_XE, P_B, P_M, P_K, P_FRONT, P_AVG, P_CELL, P_BETA = range(8)
NPAR = 8
NY = 6
# record columns
R_T, R_X, R_V, R_Z1, R_Z2, R_VOLT, R_F, R_I, R_FE = range(9)
NREC = 9
# status
OK, FULL, MAX_STEPS, NONFINITE = 0, 1, 2, 3


@njit(cache=True, inline="always")
def _row(tab, xe, x, out):
    n = tab.shape[0]
    u = x / xe * (n - 1)
    if u <= 0.0:
        u = 0.0
    i = int(u)
    if i > n - 2:
        i = n - 2
    f = u - i
    for c in range(NTAB):
        out[c] = tab[i, c] * (1.0 - f) + tab[i + 1, c] * f


FREE, HELD, AUTO = 0, 1, 2


@njit(cache=True)
def evaluate(y, W, tab, par, ydot, rw, mode):
    """dy/dt at y; W is the mean square voltage in averaged mode (else V^2 is used).
    mode: FREE (the maps are held constant beyond [0, x_e], no stop), HELD (the stroke
    rests on a stop), AUTO (a stop holds the stroke when the force pushes into it: the
    right-hand side python-control integrates). Returns (electrostatic force, current)."""
    xe = par[P_XE]
    _row(tab, xe, min(max(y[0], 0.0), xe), rw)
    return _rhs(y, W, rw, par, ydot, mode)


@njit(cache=True, inline="always")
def _rhs(y, W, rw, par, ydot, mode):
    """evaluate's right-hand side from the maps' row rw at y's stroke (the Jacobian's
    charge columns share one row: only x moves the maps)."""
    xe = par[P_XE]
    x = min(max(y[0], 0.0), xe)
    V = y[4]
    VV = W if par[P_AVG] > 0.0 else V * V
    qf = y[2] - y[3]
    Fe = rw[C0] * VV + rw[C1] * V * qf + rw[C2] * qf * qf
    net = Fe - y[5] - par[P_K] * x
    m = par[P_M]
    if m > 0.0:
        v = y[1]
        a = (net - par[P_B] * v) / m
        if mode == HELD or (mode == AUTO and ((y[0] <= 0.0 and v <= 0.0 and a < 0.0)
                                              or (y[0] >= xe and v >= 0.0 and a > 0.0))):
            v = 0.0
            a = 0.0
        xd = v
        ydot[1] = a
    else:
        xd = net / par[P_B]
        if mode == HELD or (mode == AUTO and ((y[0] <= 0.0 and xd < 0.0) or (y[0] >= xe and xd > 0.0))):
            xd = 0.0
        ydot[1] = 0.0
    ydot[0] = xd
    z1d = rw[A_Q] * y[2] + rw[B_V] * V
    ydot[2] = z1d
    if par[P_FRONT] != 0.0:
        # q_d = q_z - q_f: the front layer charges at its own rates (a_f, b_f) and is
        # renewed as the front moves at dl_z/dt over ell(x) (surrogate.py): retreating,
        # by zipped material (q_f -> q_z); advancing, by the material beyond the front,
        # which carries a share beta of the deficit of material charged at the layer's
        # own rates, q_z - b_f/b q_z (a front that comes back finds its old layer)
        rate = rw[DLZ] * xd / (par[P_CELL] * rw[W_F])
        if rate < 0.0:
            renew = -rate * y[3]
        else:
            renew = rate * (y[3] - par[P_BETA] * (1.0 - rw[B_F] / rw[B_V]) * y[2])
        ydot[3] = ((rw[A_Q] - rw[A_F]) * y[2] + rw[A_F] * y[3] + (rw[B_V] - rw[B_F]) * V - renew)
    else:
        ydot[3] = 0.0
    I = rw[I0] * V + rw[I1] * y[2] + xd * (rw[J0] * V + rw[J1] * y[2])
    return Fe, I


@njit(cache=True)
def on_stop(y, W, tab, par, rw, tmp):
    """HELD if the stroke rests on a stop with the force pushing into it, else FREE."""
    xe = par[P_XE]
    if 0.0 < y[0] < xe:
        return FREE
    evaluate(y, W, tab, par, tmp, rw, FREE)
    if y[0] <= 0.0 and tmp[0] <= 0.0 and (par[P_M] == 0.0 or tmp[1] <= 0.0):
        return HELD
    if y[0] >= xe and tmp[0] >= 0.0 and (par[P_M] == 0.0 or tmp[1] >= 0.0):
        return HELD
    return FREE


@njit(cache=True, inline="always")
def _record(rec, row, t, y, I, Fe):
    rec[row, R_T], rec[row, R_X], rec[row, R_V], rec[row, R_Z1], rec[row, R_Z2] = t, y[0], y[1], y[2], y[3]
    rec[row, R_VOLT], rec[row, R_F], rec[row, R_I], rec[row, R_FE] = y[4], y[5], I, Fe


@njit(cache=True)
def _lu(M, piv, n):
    """LU factorization with partial pivoting of the n x n M, in place."""
    for k in range(n):
        p = k
        for i in range(k + 1, n):
            if abs(M[i, k]) > abs(M[p, k]):
                p = i
        piv[k] = p
        if p != k:
            for j in range(n):
                M[k, j], M[p, j] = M[p, j], M[k, j]
        d = M[k, k] if M[k, k] != 0.0 else 1e-300
        for i in range(k + 1, n):
            M[i, k] /= d
            f = M[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    M[i, j] -= f * M[k, j]


@njit(cache=True)
def _solve(M, piv, b, n):
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
        for i in range(k + 1, n):
            b[i] -= M[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= M[i, j] * b[j]
        b[i] = s / (M[i, i] if M[i, i] != 0.0 else 1e-300)


@njit(cache=True)
def integrate(tb, v0, vs, f0, fs, w2, y0, tab, par, sc, rtol, h0, rec, max_steps):
    """Integrate over the input segments [tb[k], tb[k+1]] (voltage v0[k] + vs[k] (t - tb[k]),
    force likewise; w2[k] the mean square voltage in averaged mode). Writes one record
    row per accepted step (and the start) into rec. Returns (status, rows, steps, y).

    Steps: the Rosenbrock-W pair of Shampine's ode23s (L-stable order 2, error estimated
    at order 3, one LU per step; the Jacobian is refreshed at every step)."""
    y = y0.copy()
    F0 = np.empty(NY)
    F1 = np.empty(NY)
    F2 = np.empty(NY)
    k1 = np.empty(NY)
    k2 = np.empty(NY)
    k3 = np.empty(NY)
    yt = np.empty(NY)
    ft = np.empty(NY)
    J = np.zeros((NY, NY))
    M = np.empty((NY, NY))
    piv = np.empty(NY, dtype=np.int64)
    rw = np.empty(NTAB)
    rw0 = np.empty(NTAB)
    nrec = rec.shape[0]
    xe = par[P_XE]
    d = 1.0 / (2.0 + math.sqrt(2.0))
    e32 = 6.0 + math.sqrt(2.0)
    # columns of the Jacobian that can be nonzero: x, v (with a mass), z1, z2 (with a
    # deficit), and the inputs only on ramps
    cols = np.empty(NY, dtype=np.int64)
    steps = 0
    mode = FREE
    h = h0
    y[4] = v0[0]
    y[5] = f0[0]
    Fe, I = evaluate(y, w2[0], tab, par, F0, rw, AUTO)
    _record(rec, 0, tb[0], y, I, Fe)
    row = 1
    for seg in range(len(v0)):
        t = tb[seg]
        t_end = tb[seg + 1]
        y[4] = v0[seg]
        y[5] = f0[seg]
        W = w2[seg]
        nc = 0
        cols[nc] = 0
        nc += 1
        if par[P_M] > 0.0:
            cols[nc] = 1
            nc += 1
        cols[nc] = 2
        nc += 1
        if par[P_FRONT] != 0.0:
            cols[nc] = 3
            nc += 1
        if vs[seg] != 0.0:
            cols[nc] = 4
            nc += 1
        if fs[seg] != 0.0:
            cols[nc] = 5
            nc += 1
        evaluate(y, W, tab, par, F0, rw, FREE)
        F0[4] = vs[seg]
        F0[5] = fs[seg]
        while t < t_end - 1e-13 * max(abs(t_end), 1.0):
            if steps >= max_steps:
                return MAX_STEPS, row, steps, y
            hs = h
            last = False
            if t + 1.1 * hs >= t_end:
                hs = t_end - t
                last = True
            # Jacobian by forward differences (only the columns that can be nonzero); a
            # stroke resting on a stop is frozen for the step
            mode = on_stop(y, W, tab, par, rw, ft)
            if mode == HELD:
                F0[0] = 0.0
                F0[1] = 0.0
            # a fresh Jacobian every step: reusing it (a W-method keeps its order) saved
            # evaluations but let the error estimate miss the charge's error - it took
            # more steps for a 7x larger stroke error (measured on the standard protocol)
            _row(tab, xe, min(max(y[0], 0.0), xe), rw0)
            for c in range(nc):
                j = cols[c]
                dj = 1e-7 * max(abs(y[j]), sc[j])
                if j == 0 and y[0] >= xe:
                    dj = -dj
                for i in range(NY):
                    yt[i] = y[i]
                yt[j] += dj
                if j == 0:
                    evaluate(yt, W, tab, par, ft, rw, mode)
                else:
                    _rhs(yt, W, rw0, par, ft, mode)
                for i in range(4):
                    J[i, j] = (ft[i] - F0[i]) / dj
            if mode == HELD:
                for i in range(NY):
                    J[0, i] = 0.0
                    J[1, i] = 0.0
                    J[i, 0] = 0.0
            tries = 0
            while True:
                steps += 1
                for i in range(NY):
                    for j in range(NY):
                        M[i, j] = -d * hs * J[i, j]
                    M[i, i] += 1.0
                _lu(M, piv, NY)
                for i in range(NY):
                    k1[i] = F0[i]
                _solve(M, piv, k1, NY)
                for i in range(NY):
                    yt[i] = y[i] + 0.5 * hs * k1[i]
                evaluate(yt, W, tab, par, F1, rw, mode)
                F1[4] = vs[seg]
                F1[5] = fs[seg]
                for i in range(NY):
                    k2[i] = F1[i] - k1[i]
                _solve(M, piv, k2, NY)
                for i in range(NY):
                    k2[i] += k1[i]
                    yt[i] = y[i] + hs * k2[i]
                Fe2, I2 = evaluate(yt, W, tab, par, F2, rw, mode)
                F2[4] = vs[seg]
                F2[5] = fs[seg]
                for i in range(NY):
                    k3[i] = F2[i] - e32 * (k2[i] - F1[i]) - 2.0 * (k1[i] - F0[i])
                _solve(M, piv, k3, NY)
                err = 0.0
                for i in range(4):
                    e = hs / 6.0 * (k1[i] - 2.0 * k2[i] + k3[i]) / (rtol * (abs(y[i]) + sc[i]))
                    err = max(err, abs(e))
                if not (err == err):
                    return NONFINITE, row, steps, y
                if err <= 1.0:
                    # a step that crosses a stop is shortened to end on it (the stop
                    # is an event: the trace must not cut the corner)
                    over = 0.0
                    if yt[0] < 0.0 < y[0]:
                        over = y[0] / (y[0] - yt[0])
                    elif yt[0] > xe > y[0]:
                        over = (xe - y[0]) / (yt[0] - y[0])
                    if over == 0.0 or tries >= 6 or (yt[0] < 0.0 and yt[0] > -1e-9 * xe) \
                            or (yt[0] > xe and yt[0] < xe * (1.0 + 1e-9)):
                        break
                    tries += 1
                    hs *= min(max(over, 1e-3), 0.999) * 1.0001 if tries < 4 else 1.0001 * over
                    last = False
                    continue
                hs *= max(0.1, 0.9 / err ** (1.0 / 3.0))
                h = hs
                last = False
                if steps >= max_steps:
                    return MAX_STEPS, row, steps, y
            for i in range(NY):
                y[i] = yt[i]
            # the stops: the stroke stays in [0, x_e]; a mass hitting one stops (inelastic)
            clipped = False
            if y[0] < 0.0:
                y[0] = 0.0
                clipped = True
                if y[1] < 0.0:
                    y[1] = 0.0
            elif y[0] > xe:
                y[0] = xe
                clipped = True
                if y[1] > 0.0:
                    y[1] = 0.0
            t = t_end if last else t + hs
            if last:   # land exactly on the breakpoint's inputs
                y[4] = v0[seg] + vs[seg] * (t_end - tb[seg])
                y[5] = f0[seg] + fs[seg] * (t_end - tb[seg])
            if row >= nrec:
                return FULL, row, steps, y
            if clipped or last or mode == HELD:
                Fe, I = evaluate(y, W, tab, par, F0, rw, FREE)
                F0[4] = vs[seg]
                F0[5] = fs[seg]
            else:
                for i in range(NY):
                    F0[i] = F2[i]       # first same as last
                if 0.0 < y[0] < xe:     # inside the stops FREE and AUTO agree: F2's outputs
                    Fe, I = Fe2, I2
                else:
                    Fe, I = evaluate(y, W, tab, par, ft, rw, AUTO)
            _record(rec, row, t, y, I, Fe)
            row += 1
            h_new = hs * min(5.0, max(0.2, 0.9 / max(err, 1e-12) ** (1.0 / 3.0)))
            h = max(h, h_new) if last else h_new
            for i in range(NY):
                if not (y[i] == y[i]):
                    return NONFINITE, row, steps, y
    return OK, row, steps, y
