"""Compiled stiff integrator: TR-BDF2 with events at input breakpoints.

Why TR-BDF2: L-stable and second order (mechanics are ~1e4 times faster than the
charge relaxation), one-step (restarts at every voltage switch without history),
both implicit stages share one Newton matrix I - d h J, and J is an arrowhead so a
Newton step is O(N). The embedded third-order companion (Hosea & Shampine 1996)
gives the local error, filtered through (I - d h J)^-1 so stiff components do not
inflate it.

Inputs are piecewise linear in time between breakpoints `seg_t`: V(t) = V0 + Vs (t -
t_a) on segment [t_a, t_b], likewise the load F. Each breakpoint is an event: the
integrator lands on it, and a voltage jump there moves sigma_l, sigma_f instantly
while the interface charge stays continuous; its energy, 1/2 C dV^2 lost in the
(vanishing) source resistance, is booked in E_source.
"""
from __future__ import annotations

import math

import numpy as np
from .._jit import njit

from ..physics.equations import C_NB, C_NBORD, C_RS, C_SCHEME, NPOW, NREC, R_C, X_E, XSC
from .kernels import diagnostics_b, factor_b, jacobian_b, rhs_b, solve_b
from ..physics.nodal import NWORK
from .records import dense_outputs, energy_step, record, step_nodes
from .stepping import grow, grow_factor, shrink_factor, worst
from .stops import attracting, held, push, settle_event, sliding_point, stop_event, touching
from .trbdf2 import (DG, E0, E1, E2, EV_PREV, EV_T, EV_WA, EV_WB, G_E, G_P0, G_P1, G_ROWS, GAMMA, I_AFTERJ, I_ETA, I_F, I_F0OK,
                     I_GHOLD, I_HFACT, I_HJUMP, I_HN, I_JOK, I_STOP, I_STUCK, INTERRUPTED, MAX_STEPS, N_COUNTERS,
                     N_EVTRIES, N_FEV, N_JAC, N_OUT, N_REC, N_REJ, N_STEPS, N_TR, NONFINITE, OK, OUTPUT_FULL,
                     STEP_UNDERFLOW, W_BASE, W_DZ, W_ERR, W_F0, W_F1, W_F2, W_FBASE, W_FZ, W_RES, W_TMP, W_YTMP,
                     W_Z1, W_Z2, WTR)

NODAL_ID = 2   # kernels.NODAL
NEWTON_TOL = 0.05
MAXIT = 8


def make_workspace(n, ne, nb, h0):
    """Integrator workspace that persists between calls to `integrate`: the Newton
    matrix (Jacobian blocks and factorization), f at the current state, and the
    controller state. A stepping caller (the FMU) keeps it, so consecutive calls
    continue exactly like one call; copying it saves the complete solver state.
    The last array is f at the current state."""
    ws = (np.zeros((ne, nb, nb)), np.zeros((ne, nb)), np.zeros((ne, nb)), np.zeros((3, 4)),
          np.zeros((ne, nb, nb)), np.zeros((ne, nb)), np.zeros((ne, 3 if nb == 1 else 12)), np.zeros(4 * ne + 1),
          np.zeros(ne), np.zeros(ne), np.zeros((3, 3)), np.zeros(n))
    ist = np.array([0.0, -1.0, 1.0, h0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0])
    return ws, ist


@njit(cache=True, _nrt=False)
def _wnorm(v, y, y2, scale, rtol, nbord):
    """Scaled max-norm. An RMS would dilute the few charge states at the zipping
    front, to which the stroke is most sensitive, by sqrt(N): steps then passed the
    error test while the stroke made spurious excursions."""
    n = v.shape[0]
    mx = 0.0
    for i in range(n):
        wt = rtol * (scale[i] + max(abs(y[i]), abs(y2[i])))
        mx = worst(mx, abs(v[i]) / wt)
    return mx


@njit(cache=True, _nrt=False)
def _newton(M, wk, ws, V, F, z, base, gh, hold, w, y, scale, rtol, fb, eta):
    """Simplified Newton for a stage z = base + gh f(z) with the factored matrix.
    `eta` carries the contraction estimate theta/(1 - theta) from earlier iterations
    (Hairer & Wanner's RADAU5 strategy): one iteration suffices when Newton contracts
    fast. With `hold`, the stroke is stuck at a force jump or rests on a stop (the
    mechanical rates are zero). Returns (converged, iterations, eta)."""
    n = z.shape[0]
    nbord = M[0][C_NBORD]
    fz, res, dz = w[W_FZ], w[W_RES], w[W_DZ]
    nprev = 0.0
    for it in range(MAXIT):
        rhs_b(M, wk, V, F, z, fz)
        if hold:
            for i in range(nbord):
                fz[i] = 0.0
        for i in range(n):
            res[i] = -(z[i] - base[i] - gh * fz[i])
        solve_b(M, ws, gh, fb, res, dz)
        for i in range(n):
            z[i] += dz[i]
        nrm = _wnorm(dz, y, z, scale, rtol, nbord)
        if not math.isfinite(nrm):
            return False, it + 1, eta
        if it == 0:
            if eta * nrm <= NEWTON_TOL:
                return True, 1, eta
        else:
            th = nrm / nprev
            if th > 0.9:
                return False, it + 1, eta
            eta = th / (1.0 - th)
            if eta * nrm <= NEWTON_TOL:
                return True, it + 1, eta
        nprev = nrm
    return False, MAXIT, eta


@njit(cache=True, _nrt=False)
def _begin_segment(M, wk, ws, ist, cnt, w, y, sidx, seg_t, seg_V0, seg_Vs, seg_F0, seg_Fs, V_prev, want_energy, eg,
                   row, xc, eps_x):
    """Jump handling at the breakpoint that starts segment sidx. A voltage jump moves
    charge instantly (continuum scheme; its energy is booked). Where neither input jumps,
    f and the Newton matrix carry on (a stepping caller passes the same input again);
    otherwise f is taken at the new inputs, the Newton matrix is flipped (a polarity
    inversion) or dropped, and a stroke stuck at a force jump or on a stop stays or
    leaves with the new force."""
    cfg, mat = M[0], M[2]
    nbord = cfg[C_NBORD]
    f0, tmp, ytmp = w[W_F0], w[W_TMP], w[W_YTMP]
    ta = seg_t[sidx]
    V0, F0 = seg_V0[sidx], seg_F0[sidx]
    if sidx == 0:
        Vleft = V_prev
        Fleft = ist[I_F]      # only read once a call has written it (jac_ok or f0 valid)
    else:
        Vleft = seg_V0[sidx - 1] + seg_Vs[sidx - 1] * (ta - seg_t[sidx - 1])
        Fleft = seg_F0[sidx - 1] + seg_Fs[sidx - 1] * (ta - seg_t[sidx - 1])
    smooth = V0 == Vleft and F0 == Fleft and seg_Vs[sidx] == 0.0 and seg_Fs[sidx] == 0.0 and ist[I_F0OK] > 0.0
    if want_energy and cfg[C_SCHEME] != 1 and cfg[C_RS] == 0 and V0 != Vleft:
        rhs_b(M, wk, Vleft, F0, y, f0)
        diagnostics_b(M, wk, Vleft, 0.0, F0, y, f0, row, eg[G_P0])
        C = row[R_C]
        dV = V0 - Vleft
        eg[G_E, 0] += V0 * C * dV
        eg[G_E, 3] += 0.5 * C * dV * dV
    if smooth:
        fkeep = ws[11]
        for i in range(y.shape[0]):
            f0[i] = fkeep[i]
        return
    rhs_b(M, wk, V0, F0, y, f0)
    cnt[N_FEV] += 1
    if V0 != Vleft:
        if ist[I_HJUMP] > 0.0:
            ist[I_HN] = min(ist[I_HN], ist[I_HJUMP])
        ist[I_AFTERJ] = 1.0
    if ist[I_JOK] > 0.0 and V0 == -Vleft and V0 != 0.0 and F0 == Fleft and cfg[C_RS] == 0:
        # polarity inversion: the q-x couplings scale with A = eps_l V - T0 q and flip
        # sign, the rest is unchanged for small q; a good Newton matrix for free
        # (Newton's convergence test still guards the result)
        Jeb, Jbe = ws[1], ws[2]
        for i in range(Jeb.shape[0]):
            for c in range(cfg[C_NB]):
                Jeb[i, c] = -Jeb[i, c]
                if c == 0 or cfg[C_SCHEME] != NODAL_ID:   # the force's P-derivative ~ P: unchanged
                    Jbe[i, c] = -Jbe[i, c]
        ist[I_HFACT] = -1.0
    else:
        ist[I_JOK] = 0.0
    stuck = int(ist[I_STUCK])
    if stuck >= 0:
        if attracting(M, wk, V0, F0, y, xc[stuck], eps_x, tmp, ytmp):
            f0[0] = 0.0
        else:
            ist[I_STUCK] = -1.0
    touch = touching(y, nbord, mat[X_E])
    new_stop = 0
    if touch != 0:
        g = push(M, wk, V0, F0, y, tmp)[0]
        ist[I_GHOLD] = g
        cnt[N_FEV] += 1
        if held(touch, g):
            new_stop = touch
    if new_stop != int(ist[I_STOP]):
        ist[I_STOP] = new_stop
        ist[I_JOK] = 0.0
        cnt[N_EVTRIES] = 0
    if new_stop != 0:
        for i in range(nbord):
            f0[i] = 0.0


@njit(cache=True, _nrt=False)
def _newton_matrix(M, wk, ws, ist, cnt, w, y, V, F, h, fb):
    """The Newton matrix I - d h J for a step h: the Jacobian is kept across steps while
    Newton converges fast; it is renewed at every breakpoint (unless flipped there), on
    slow or failed convergence and when the stroke sticks or is released. Returns
    whether it was renewed now."""
    fresh = False
    if not ist[I_JOK] > 0.0:
        jacobian_b(M, wk, ws, V, F, y, w[W_FBASE], w[W_TMP], w[W_YTMP])
        if ist[I_STUCK] >= 0 or ist[I_STOP] != 0:    # the stroke is held: its rows decouple
            nbord = M[0][C_NBORD]
            Jbe, Jbb = ws[2], ws[3]
            for a in range(Jbb.shape[0]):
                for b in range(Jbb.shape[1]):
                    if a < nbord or b < nbord:   # (a series resistance's V_d keeps its own)
                        Jbb[a, b] = 0.0
            Jbe[:, :] = 0.0
        cnt[N_JAC] += 1
        cnt[N_FEV] += 2
        ist[I_JOK] = 1.0
        fresh = True
        ist[I_HFACT] = -1.0
        ist[I_ETA] = 1.0
    if h != ist[I_HFACT]:
        factor_b(M, ws, DG * h, fb)
        ist[I_HFACT] = h
    ist[I_ETA] = max(ist[I_ETA], 1e-16) ** 0.8
    return fresh


@njit(cache=True, _nrt=False)
def _stages(M, wk, ws, ist, cnt, w, y, t, h, ta, V0, Vs, F0, Fs, hold, scale, rtol, fb):
    """TR-BDF2's two implicit stages: the trapezoidal rule to t + gamma h (z1), then BDF2
    to t + h (z2), each solved by simplified Newton. Returns (converged, slow: more than
    two iterations in a stage)."""
    gh = DG * h
    x_e = M[2][X_E]
    n = y.shape[0]
    z1, z2, f0, f1, base = w[W_Z1], w[W_Z2], w[W_F0], w[W_F1], w[W_BASE]
    tg = t + GAMMA * h
    for i in range(n):
        z1[i] = y[i] + GAMMA * h * f0[i]
        base[i] = y[i] + gh * f0[i]
    z1[0] = min(max(z1[0], 0.0), x_e)     # predictors start inside the stops
    conv, its, eta = _newton(M, wk, ws, V0 + Vs * (tg - ta), F0 + Fs * (tg - ta), z1, base, gh, hold, w, y, scale,
                             rtol, fb, ist[I_ETA])
    ist[I_ETA] = eta
    cnt[N_FEV] += its
    slow = its > 2
    if not conv:
        return False, slow
    for i in range(n):
        f1[i] = (z1[i] - base[i]) / gh
    t2 = t + h
    for i in range(n):
        z2[i] = z1[i] + (1.0 - GAMMA) * h * f1[i]
        base[i] = y[i] + h * WTR * (f0[i] + f1[i])
    z2[0] = min(max(z2[0], 0.0), x_e)
    conv, its, eta = _newton(M, wk, ws, V0 + Vs * (t2 - ta), F0 + Fs * (t2 - ta), z2, base, gh, hold, w, y, scale,
                             rtol, fb, eta)
    ist[I_ETA] = eta
    cnt[N_FEV] += its
    return conv, slow or its > 2


@njit(cache=True, _nrt=False)
def _error_norm(M, ws, w, y, h, hold, scale, rtol, fb):
    """f at the end stage, and the embedded companion's local error, filtered through
    (I - d h J)^-1 (stiff components do not inflate it), in the scaled max-norm."""
    gh = DG * h
    n = y.shape[0]
    nbord = M[0][C_NBORD]
    z2, f0, f1, f2, base, res, err = w[W_Z2], w[W_F0], w[W_F1], w[W_F2], w[W_BASE], w[W_RES], w[W_ERR]
    for i in range(n):
        f2[i] = (z2[i] - base[i]) / gh
    if hold:
        for i in range(nbord):
            f2[i] = 0.0
    for i in range(n):
        res[i] = h * (E0 * f0[i] + E1 * f1[i] + E2 * f2[i])
    solve_b(M, ws, gh, fb, res, err)
    return _wnorm(err, y, z2, scale, rtol, nbord)


@njit(cache=True)
def integrate(cfg, geo, mat, law, lawp, y0, seg_t, seg_V0, seg_Vs, seg_F0, seg_Fs, V_prev,
              rtol, scale, t_out, want_energy, store_states, max_steps, xc, ws, ist, one_step, want_trace,
              max_rows, interrupt):
    """Integrate from seg_t[0] to seg_t[-1]. Records every accepted step, or the times
    t_out if given (dense output, records.dense_outputs). Returns (rec, states, stats,
    y_end, trace); with want_trace, trace holds the stroke of every accepted step as rows
    (t_end, x at the stage t + gamma h, x_end), after a first row (t0, x0, x0): the
    solver's own dense record of x(t), from which the metrics are computed whatever
    the output sampling.

    Stops and force jumps (xc: strokes where the force jumps, the paper scheme's
    midpoint crossings; empty otherwise) are events: stops.py. max_rows: the output
    record's row limit when every step is recorded (status OUTPUT_FULL when reached;
    t_out is checked by the caller).

    ws, ist: the persistent workspace and controller state (make_workspace, trbdf2.I_*),
    updated in place. A breakpoint where neither input jumps keeps f and the Newton matrix.
    one_step: return after the first accepted step, recording its start, stage and end
    (a stepping caller interpolates its communication points there, see
    dfa_model.numerics.stepper).

    interrupt: one int64, the caller's interrupt flag (dfa_model.interrupt), read before
    every step and every dense output: once it is nonzero the call returns with status
    INTERRUPTED and empty records (the run is abandoned). Never written here; the zero of a
    caller that does not interrupt costs a load per step."""
    n = y0.shape[0]
    nbord = cfg[C_NBORD]
    M = (cfg, geo, mat, law, lawp)
    wk = (np.zeros(6), np.zeros(NWORK), ws[6], ws[7])
    y = y0.copy()
    # the step's vectors (trbdf2.W_*), a tuple: a member passes to the pieces as it is,
    # where a row of a 2-D array would be a new view at every use
    w = (np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n),
         np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n), np.empty(n))
    f0, z1, z2, f2 = w[W_F0], w[W_Z1], w[W_Z2], w[W_F2]
    eg = np.zeros((G_ROWS, NPOW))
    row = np.zeros(NREC)
    cnt = np.zeros(N_COUNTERS, np.int64)
    ev = np.empty(4)
    ev[EV_T], ev[EV_WA], ev[EV_WB], ev[EV_PREV] = -math.inf, 1.0, 1.0, 0.0
    grid = t_out.shape[0] > 0
    rec = np.zeros((min(1024, t_out.shape[0] + 2) if grid else (8 if one_step else 1024), NREC))
    states = np.zeros((1024 if store_states else 1, n))
    trace = np.zeros((1024 if want_trace else 1, 3))
    status = OK
    done = False
    fb = nbord - 1
    sliding = xc.shape[0] > 0 and nbord == 1
    eps_x = 1e-9 * mat[XSC]
    tol_x = rtol * scale[0]       # how far past a stop a step may end without a retry
    t = seg_t[0]
    if want_trace:
        trace[0, 0], trace[0, 1], trace[0, 2] = t, y[0], y[0]
        cnt[N_TR] = 1
    nseg = seg_t.shape[0] - 1
    hmin = 1e-14 * max(1.0, abs(seg_t[nseg]))
    for sidx in range(nseg):
        ta, tb = seg_t[sidx], seg_t[sidx + 1]
        V0, Vs, F0, Fs = seg_V0[sidx], seg_Vs[sidx], seg_F0[sidx], seg_Fs[sidx]
        _begin_segment(M, wk, ws, ist, cnt, w, y, sidx, seg_t, seg_V0, seg_Vs, seg_F0, seg_Fs, V_prev, want_energy, eg,
                       row, xc, eps_x)
        if sidx == 0 and not one_step and ((not grid) or t_out[0] <= t):
            rec, states = _keep_row(M, wk, cnt, eg[G_P0], eg, t, V0, Vs, F0, y, f0, rec, states, store_states,
                                        grid)
        if want_energy:
            diagnostics_b(M, wk, V0, Vs, F0, y, f0, row, eg[G_P0])
        while t < tb and status == OK and not done:
            h = ist[I_HN]                 # the step the controller wants, clipped to land on tb
            if tb - t <= h * (1.0 + 1e-9) or tb - t < 2.0 * hmin:
                h = tb - t
            status = _may_step(cnt, max_steps, interrupt, max_rows, grid)
            if status != OK:
                break
            fresh = _newton_matrix(M, wk, ws, ist, cnt, w, y, V0 + Vs * (t - ta), F0 + Fs * (t - ta), h, fb)
            hold = ist[I_STUCK] >= 0 or ist[I_STOP] != 0
            ok, slow = _stages(M, wk, ws, ist, cnt, w, y, t, h, ta, V0, Vs, F0, Fs, hold, scale, rtol, fb)
            if slow:
                ist[I_JOK] = 0.0
            en = _error_norm(M, ws, w, y, h, hold, scale, rtol, fb) if ok else 0.0
            if not (ok and en <= 1.0):    # rejected: retry smaller (or with a fresh Jacobian)
                status = _reject(ist, cnt, h, ok, fresh, en, hmin)
                continue
            tg, t2 = t + GAMMA * h, t + h
            Vg, Fg, V2, F2 = V0 + Vs * (tg - ta), F0 + Fs * (tg - ta), V0 + Vs * (t2 - ta), F0 + Fs * (t2 - ta)
            event, g2, th = stop_event(M, wk, ist, cnt, ev, w, y, t, h, V2, F2, rtol, tol_x)
            if th > 0.0:                  # retried to end at the stop event
                ist[I_HN] = h * th
                continue
            cnt[N_STEPS] += 1
            if sliding:
                sliding_point(M, wk, ist, cnt, w, y, xc, eps_x, V2, F2)
            settle_event(M, wk, ist, cnt, ev, w, event, g2, t, h, V2, F2, want_energy, eg)
            if want_energy:
                energy_step(M, wk, w, eg, row, h, Vg, Fg, V2, F2, Vs)
            if one_step:
                rec = step_nodes(M, wk, w, eg, y, t, h, ta, V0, Vs, F0, Fs, Vg, Fg, V2, F2, rec, cnt)
            if grid:
                rec, states, status = dense_outputs(M, wk, w, eg, y, t, h, ta, V0, Vs, F0, Fs, t_out, want_energy,
                                                    store_states, rec, states, cnt, interrupt)
            t = t + h
            if tb - t < 2.0 * hmin:
                t = tb
            for i in range(n):
                y[i] = z2[i]
                f0[i] = f2[i]
            if want_trace:
                trace = grow(trace, cnt[N_TR])
                trace[cnt[N_TR], 0], trace[cnt[N_TR], 1], trace[cnt[N_TR], 2] = t, min(max(z1[0], 0.0), mat[X_E]), y[0]
                cnt[N_TR] += 1
            if not grid and not one_step:
                rec, states = _keep_row(M, wk, cnt, eg[G_P1], eg, t, V2, Vs, F2, y, f0, rec, states, store_states,
                                        grid)
            _next_step(ist, ev, h, t, en)
            done = one_step
        if status != OK:
            break
        # what the next call continues from (f0 belongs to V, F at the segment end)
        ws[11][:] = f0
        ist[I_F] = F0 + Fs * (t - ta)
        ist[I_F0OK] = 1.0 if Vs == 0.0 and Fs == 0.0 else 0.0
        if done:
            break
    nrec, ntr = (0, 0) if status == INTERRUPTED else (cnt[N_REC], cnt[N_TR])   # abandoned: no copies
    stats = np.array([cnt[N_STEPS], cnt[N_REJ], cnt[N_FEV], cnt[N_JAC], status, t], dtype=np.float64)
    return (rec[:nrec].copy(), states[:nrec].copy() if store_states else states[:0].copy(), stats, y,
            trace[:ntr].copy())


@njit(cache=True, inline="always")
def _keep_row(M, wk, cnt, P, eg, t, V, Vs, F, y, f, rec, states, store_states, grid):
    """Record the state y at t (the first row, or an accepted step's end; P receives
    the powers)."""
    nrec = cnt[N_REC]
    rec = grow(rec, nrec)
    record(M, wk, t, V, Vs, F, y, f, eg[G_E], rec[nrec], P)
    if store_states:
        states = grow(states, nrec)
        states[nrec, :] = y
    cnt[N_REC] = nrec + 1
    if grid:
        cnt[N_OUT] += 1
    return rec, states


@njit(cache=True, inline="always")
def _may_step(cnt, max_steps, interrupt, max_rows, grid):
    """OK, or why no further step may be taken."""
    if cnt[N_STEPS] + cnt[N_REJ] >= max_steps:
        return MAX_STEPS
    if interrupt[0] != 0:
        return INTERRUPTED
    if cnt[N_REC] >= max_rows and not grid:
        return OUTPUT_FULL
    return OK


@njit(cache=True, inline="always")
def _reject(ist, cnt, h, converged, fresh, en, hmin):
    """A rejected step: Newton failed (retry with a fresh Jacobian before shrinking the
    step), the error was not finite, or too large. Returns the status (OK: retry)."""
    cnt[N_REJ] += 1
    if not converged:
        ist[I_HN] = 0.25 * h if fresh else h
        ist[I_JOK] = 0.0
        return STEP_UNDERFLOW if ist[I_HN] < hmin else OK
    if not math.isfinite(en):
        ist[I_HN] = 0.25 * h
        return NONFINITE if ist[I_HN] < hmin else OK
    ist[I_HN] = h * shrink_factor(en, 0.2)
    return STEP_UNDERFLOW if ist[I_HN] < hmin else OK


@njit(cache=True, inline="always")
def _next_step(ist, ev, h, t, en):
    """The step size after an accepted step h ending at t. After a voltage jump, the first
    step proposed is kept for the next jump: a jump starts a transient (a stroke dip at
    an inversion, an R_s C charging of a fraction of a millisecond) that the previous
    segment's last, long step overshot (shrinking to it took 3 rejected steps at every
    switch of a 30 Hz reset at rtol 1e-5, ~8 with a series resistance). A located stop
    event still ahead: the step stays inside its bracket."""
    hn = ist[I_HN]
    fac = grow_factor(en)
    hn = h * fac if h >= hn else max(hn, h * fac)
    if ist[I_AFTERJ] > 0.0:
        ist[I_HJUMP] = hn
        ist[I_AFTERJ] = 0.0
    if ev[EV_T] > t:
        hn = min(hn, ev[EV_T] - t)
    ist[I_HN] = hn
