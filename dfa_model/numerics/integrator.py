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

from ..physics.equations import C_NB, C_NBORD, C_RS, C_SCHEME, K, MASS, NPOW, NREC, R_C, R_EIN, R_T, R_X, X_E, XSC
from .kernels import diagnostics, factor, jacobian, solve
from ..physics.nodal import NWORK

NODAL_ID = 2   # kernels.NODAL
from .kernels import rhs as rhs_any

GAMMA = 2.0 - math.sqrt(2.0)
DG = GAMMA / 2.0
WTR = math.sqrt(2.0) / 4.0
# b - b_hat of the embedded companion: [(4w-1)/3, -1/3, 2d/3]
E0 = (4.0 * WTR - 1.0) / 3.0
E1 = -1.0 / 3.0
E2 = 2.0 * DG / 3.0
NEWTON_TOL = 0.05
MAXIT = 8

OK, MAX_STEPS, STEP_UNDERFLOW, NONFINITE, OUTPUT_FULL, INTERRUPTED = 0, 1, 2, 3, 4, 5
# carried controller state `ist` (see make_workspace): Jacobian valid, step of the stored
# factorization, Newton contraction estimate, next step size, stuck index, f0 valid, the
# load at the end of the last call (its voltage is the caller's V_prev), and the stop the
# stroke rests on (-1: x = 0, +1: x = x_e, 0: free) with the net zipping force there, the
# step to start the next voltage jump with (-1: none yet) and whether the step after the
# last jump is still to come
I_JOK, I_HFACT, I_ETA, I_HN, I_STUCK, I_F0OK, I_F, I_STOP, I_GHOLD, I_HJUMP, I_AFTERJ = 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10
# impact energy slot of the energy accumulators (equations.NPOW)
E_IMPACT = 6
# a stop event (impact, release) is located by at most this many retried steps
EV_TRIES = 6


def make_workspace(n, ne, nb, h0):
    """Integrator workspace that persists between calls to `integrate`: the Newton
    matrix (Jacobian blocks and factorization), f at the current state, and the
    controller state. A stepping caller (the FMU) keeps it, so consecutive calls
    continue exactly like one call; copying it saves the complete solver state.
    The last array is f at the current state."""
    ws = (np.zeros((ne, nb, nb)), np.zeros((ne, nb)), np.zeros((ne, nb)), np.zeros((3, 4)),
          np.zeros((ne, nb, nb)), np.zeros((ne, nb)), np.zeros((ne, 3 if nb == 1 else 9)), np.zeros(3 * ne + 1),
          np.zeros(ne), np.zeros(ne), np.zeros((3, 3)), np.zeros(n))
    ist = np.array([0.0, -1.0, 1.0, h0, -1.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0])
    return ws, ist


@njit(cache=True)
def _wnorm(v, y, y2, scale, rtol, nbord):
    """Scaled max-norm. An RMS would dilute the few charge states at the zipping
    front, to which the stroke is most sensitive, by sqrt(N): steps then passed the
    error test while the stroke made spurious excursions."""
    n = v.shape[0]
    mx = 0.0
    for i in range(n):
        wt = rtol * (scale[i] + max(abs(y[i]), abs(y2[i])))
        mx = max(mx, abs(v[i]) / wt)
    return mx


@njit(cache=True)
def _grow(buf, nrow):
    if nrow < buf.shape[0]:
        return buf
    nb = np.empty((2 * buf.shape[0], buf.shape[1]))
    nb[:buf.shape[0]] = buf
    return nb


@njit(cache=True)
def _record(cfg, geo, mat, law, lawp, t, V, dVdt, F, y, ydot, E, kin, work, row, P):
    row[:] = 0.0
    diagnostics(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, row, P)
    row[R_T] = t
    row[R_X] = y[0]
    for i in range(NPOW):
        row[R_EIN + i] = E[i]


@njit(cache=True)
def _dense_record(cfg, geo, mat, law, lawp, s, h, to, y, z1, z2, V, Vs, F, E, yi, ydi, kin, work, row, P):
    """Record the outputs at time `to`, the fraction s of the step of size h: the
    quadratic through the step's values y (start), z1 (stage, s = gamma) and z2 (end).
    Values only: a Hermite cubic would carry the fast modes' start slopes, h f, across
    a long stiff step and overshoot between the ends."""
    n = y.shape[0]
    g = GAMMA
    l0 = (s - g) * (s - 1.0) / g
    l1 = s * (s - 1.0) / (g * (g - 1.0))
    l2 = s * (s - g) / (1.0 - g)
    d0 = (2.0 * s - g - 1.0) / (g * h)
    d1 = (2.0 * s - 1.0) / (g * (g - 1.0) * h)
    d2 = (2.0 * s - g) / ((1.0 - g) * h)
    for i in range(n):
        yi[i] = l0 * y[i] + l1 * z1[i] + l2 * z2[i]
        ydi[i] = d0 * y[i] + d1 * z1[i] + d2 * z2[i]
    yi[0] = min(max(yi[0], 0.0), mat[X_E])     # the interpolant's overshoot past a stop
    if y[0] == z1[0] and z1[0] == z2[0]:       # held (a stop, a sliding point): exactly
        yi[0] = y[0]
        ydi[0] = 0.0
    _record(cfg, geo, mat, law, lawp, to, V, Vs, F, yi, ydi, E, kin, work, row, P)


@njit(cache=True)
def _newton(cfg, geo, mat, law, lawp, V, F, z, base, gh, held, fz, res, dz, y, scale, rtol, Winv, zeta, Jbe, Jbb, tri,
            cp, dinv, S, fb, kin, work, jbe, eta):
    """Simplified Newton for a stage z = base + gh f(z) with the factored matrix.
    `eta` carries the contraction estimate theta/(1 - theta) from earlier iterations
    (Hairer & Wanner's RADAU5 strategy): one iteration suffices when Newton contracts
    fast. With `held`, the stroke is stuck at a force jump or rests on a stop (the
    mechanical rates are zero). Returns (converged, iterations, eta)."""
    n = z.shape[0]
    nbord = cfg[C_NBORD]
    nprev = 0.0
    for it in range(MAXIT):
        rhs_any(cfg, geo, mat, law, lawp, V, F, z, fz, kin, work, tri, jbe)
        if held:
            for i in range(nbord):
                fz[i] = 0.0
        for i in range(n):
            res[i] = -(z[i] - base[i] - gh * fz[i])
        solve(cfg, mat, gh, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, res, dz)
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


@njit(cache=True)
def _net(cfg, geo, mat, law, lawp, V, F, y, x, tmp, ytmp, kin, work, tri, jbe):
    """Stroke rate dx/dt with the stroke set to x (other states as in y)."""
    for i in range(y.shape[0]):
        ytmp[i] = y[i]
    ytmp[0] = x
    rhs_any(cfg, geo, mat, law, lawp, V, F, ytmp, tmp, kin, work, tri, jbe)
    return tmp[0]


@njit(cache=True)
def _attracting(cfg, geo, mat, law, lawp, V, F, y, xk, eps, tmp, ytmp, kin, work, tri, jbe):
    return (_net(cfg, geo, mat, law, lawp, V, F, y, xk - eps, tmp, ytmp, kin, work, tri, jbe) > 0.0 and
            _net(cfg, geo, mat, law, lawp, V, F, y, xk + eps, tmp, ytmp, kin, work, tri, jbe) < 0.0)


@njit(cache=True)
def _push(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work, tri, jbe):
    """Net force towards zipping at state y, -(F + k x + F_e) (N), and its scale
    |F| + |k x| + |F_e| (for a tolerance); ydot receives f(y)."""
    Fe = rhs_any(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work, tri, jbe)
    return -(F + mat[K] * y[0] + Fe), abs(F) + abs(mat[K] * y[0]) + abs(Fe)


@njit(cache=True)
def _touching(y, nbord, x_e):
    """The stop the state touches, moving into it or at rest: -1 (x = 0), +1 (x_e), 0."""
    if y[0] <= 0.0 and (nbord == 1 or y[1] <= 0.0):
        return -1
    if y[0] >= x_e and (nbord == 1 or y[1] >= 0.0):
        return 1
    return 0


@njit(cache=True)
def _held(stop, g):
    """Whether a stroke on `stop` stays there under the net zipping force g."""
    return (stop < 0 and g <= 0.0) or (stop > 0 and g >= 0.0)


@njit(cache=True)
def _event_retry(t, h, f0, f1, ev_t, wa, wb, prev):
    """The step [t, t + h] ends past a stop event (event function f0 at t, f1 at t + h,
    opposite signs). Returns the fraction of the step to try next, the secant root with
    Illinois weights, and the bracket's new weights and last outcome: the far end is new
    (unless the step only re-reached the old one, ev_t), the near end kept, and a near
    end kept twice in a row has its weight halved."""
    if t + h != ev_t:
        wa = wa * 0.5 if prev == 1 else wa
        wb = 1.0
        prev = 1
    return min(0.999, max(1e-3, wa * f0 / (wa * f0 - wb * f1))), wa, wb, prev


@njit(cache=True)
def integrate(cfg, geo, mat, law, lawp, y0, seg_t, seg_V0, seg_Vs, seg_F0, seg_Fs, V_prev,
              rtol, scale, t_out, want_energy, store_states, max_steps, xc, ws, ist, one_step, want_trace,
              max_rows, interrupt):
    """Integrate from seg_t[0] to seg_t[-1]. Records every accepted step, or the times
    t_out if given (dense output, _dense_record). Returns (rec, states, stats, y_end,
    trace); with want_trace, trace holds the stroke of every accepted step as rows
    (t_end, x at the stage t + gamma h, x_end), after a first row (t0, x0, x0): the
    solver's own dense record of x(t), from which the metrics are computed whatever
    the output sampling.

    Stops: the stroke lies in [0, x_e]. A step that ends past a stop is retried to end
    there (the crossing located by linear interpolation, at most EV_TRIES times); on
    the stop the motion is held (inelastic impact: the kinetic energy is booked) while
    the net force pushes into it, and released when it no longer does (located the
    same way).

    max_rows: the output record's row limit when every step is recorded (status
    OUTPUT_FULL when reached; t_out is checked by the caller).

    xc: strokes where the force jumps (the paper scheme's midpoint crossings; empty
    otherwise). There the stroke equation has a discontinuous right-hand side and the
    equilibrium is a sliding point: the stroke sticks at a crossing while the force
    pushes towards it from both sides and is released when it no longer does.

    ws, ist: the persistent workspace and controller state (make_workspace), updated
    in place. A breakpoint where neither input jumps keeps f and the Newton matrix.
    one_step: return after the first accepted step, recording its start, stage and end
    (a stepping caller interpolates its communication points there, see
    dfa_model.numerics.stepper).

    interrupt: one int64, the caller's interrupt flag (dfa_model.interrupt), read before
    every step and every dense output: once it is nonzero the call returns with status
    INTERRUPTED and empty records (the run is abandoned). Never written here; the zero of a
    caller that does not interrupt costs a load per step."""
    n = y0.shape[0]
    nb = cfg[C_NB]
    nbord = cfg[C_NBORD]
    y = y0.copy()
    z1 = np.empty(n)
    z2 = np.empty(n)
    f0 = np.empty(n)
    f1 = np.empty(n)
    f2 = np.empty(n)
    fz = np.empty(n)
    res = np.empty(n)
    dz = np.empty(n)
    err = np.empty(n)
    tmp = np.empty(n)
    ytmp = np.empty(n)
    yi = np.empty(n)
    ydi = np.empty(n)
    fbase = np.empty(n)
    base = np.empty(n)
    kin = np.zeros(6)
    work = np.zeros(NWORK)
    Jee, Jeb, Jbe, Jbb, Winv, zeta, tri, jbe, cp, dinv, S, fkeep = ws
    E = np.zeros(NPOW)
    Eold = np.zeros(NPOW)
    P0 = np.zeros(NPOW)
    P1 = np.zeros(NPOW)
    P2 = np.zeros(NPOW)
    row = np.zeros(NREC)
    Eint = np.zeros(NPOW)
    rec = np.zeros((min(1024, t_out.shape[0] + 2) if t_out.shape[0] > 0 else (8 if one_step else 1024), NREC))
    states = np.zeros((1024 if store_states else 1, n))
    trace = np.zeros((1024 if want_trace else 1, 3))
    ntr = 0
    nrec = 0
    nfev = 0
    njac = 0
    nsteps = 0
    nrej = 0
    status = OK
    done = False
    grid = t_out.shape[0] > 0
    kout = 0
    nseg = seg_t.shape[0] - 1
    jac_ok = ist[I_JOK] > 0.0
    h_fact = ist[I_HFACT]
    eta = ist[I_ETA]              # Newton contraction estimate theta/(1 - theta)
    fb = nbord - 1
    stuck = int(ist[I_STUCK])     # index into xc while sliding
    sliding = xc.shape[0] > 0 and nbord == 1
    eps_x = 1e-9 * mat[XSC]
    stop = int(ist[I_STOP])       # the stop the stroke rests on (held), or 0
    x_e = mat[X_E]
    tol_x = rtol * scale[0]       # how far past a stop a step may end without a retry
    g_hold = ist[I_GHOLD]         # net zipping force at y while held
    ev_tries = 0
    # a stop event being located: bracket [t (held/short side), ev_t (past the event)],
    # regula falsi with the Illinois rule (an end kept twice in a row has its value halved)
    ev_t = -math.inf
    ev_wa = 1.0                   # weight of the near end's value
    ev_wb = 1.0                   # weight of the far end's value
    ev_prev = 0                   # last trial's outcome: 1 past the event, 2 short of it
    t = seg_t[0]
    if want_trace:
        trace[0, 0] = t
        trace[0, 1] = y[0]
        trace[0, 2] = y[0]
        ntr = 1
    hn = ist[I_HN]
    h = hn
    # the step the controller proposed after the first step accepted past the last
    # voltage jump: the next jump starts there rather than at the step the previous
    # segment ended with. A jump starts a transient (a stroke dip at an inversion, an
    # R_s C charging of a fraction of a millisecond) that the previous segment's last,
    # long step overshot: shrinking to it took 3 rejected steps at every switch of a
    # 30 Hz reset at rtol 1e-5, ~8 with a series resistance
    h_jump = ist[I_HJUMP]
    after_jump = ist[I_AFTERJ] > 0.0
    t_end = seg_t[nseg]
    hmin = 1e-14 * max(1.0, abs(t_end))
    for sidx in range(nseg):
        ta, tb = seg_t[sidx], seg_t[sidx + 1]
        V0, Vs, F0, Fs = seg_V0[sidx], seg_Vs[sidx], seg_F0[sidx], seg_Fs[sidx]
        if sidx == 0:
            Vleft = V_prev
            Fleft = ist[I_F]      # only read once a call has written it (jac_ok or f0 valid)
        else:
            Vleft = seg_V0[sidx - 1] + seg_Vs[sidx - 1] * (ta - seg_t[sidx - 1])
            Fleft = seg_F0[sidx - 1] + seg_Fs[sidx - 1] * (ta - seg_t[sidx - 1])
        # no jump in either input: not an event for the solver state (a stepping caller
        # passes the same input again); f and the Newton matrix carry on
        smooth = V0 == Vleft and F0 == Fleft and Vs == 0.0 and Fs == 0.0 and ist[I_F0OK] > 0.0
        # a voltage jump moves charge instantly (continuum scheme): book its energy
        if want_energy and cfg[C_SCHEME] != 1 and cfg[C_RS] == 0 and V0 != Vleft:
            rhs_any(cfg, geo, mat, law, lawp, Vleft, F0, y, f0, kin, work, tri, jbe)
            diagnostics(cfg, geo, mat, law, lawp, Vleft, 0.0, F0, y, f0, kin, work, row, P0)
            C = row[R_C]
            dV = V0 - Vleft
            E[0] += V0 * C * dV
            E[3] += 0.5 * C * dV * dV
        if smooth:
            for i in range(n):
                f0[i] = fkeep[i]
        else:
            rhs_any(cfg, geo, mat, law, lawp, V0, F0, y, f0, kin, work, tri, jbe)
            nfev += 1
            if V0 != Vleft:
                if h_jump > 0.0:
                    hn = min(hn, h_jump)
                after_jump = True
            if jac_ok and V0 == -Vleft and V0 != 0.0 and F0 == Fleft and cfg[C_RS] == 0:
                # polarity inversion: the q-x couplings scale with A = eps_l V - T0 q and
                # flip sign, the rest is unchanged for small q; a good Newton matrix for
                # free (Newton's convergence test still guards the result)
                for i in range(Jeb.shape[0]):
                    for c in range(nb):
                        Jeb[i, c] = -Jeb[i, c]
                        if c == 0 or cfg[C_SCHEME] != NODAL_ID:   # the force's P-derivative ~ P: unchanged
                            Jbe[i, c] = -Jbe[i, c]
                h_fact = -1.0
            else:
                jac_ok = False
            if stuck >= 0:
                if _attracting(cfg, geo, mat, law, lawp, V0, F0, y, xc[stuck], eps_x, tmp, ytmp, kin, work, tri,
                               jbe):
                    f0[0] = 0.0
                else:
                    stuck = -1
            # inputs jumped: on a stop, the stroke stays or leaves with the new force
            touch = _touching(y, nbord, x_e)
            new_stop = 0
            if touch != 0:
                g_hold = _push(cfg, geo, mat, law, lawp, V0, F0, y, tmp, kin, work, tri, jbe)[0]
                nfev += 1
                if _held(touch, g_hold):
                    new_stop = touch
            if new_stop != stop:
                stop = new_stop
                jac_ok = False
                ev_tries = 0
            if stop != 0:
                for i in range(nbord):
                    f0[i] = 0.0
        if sidx == 0 and not one_step:
            if (not grid) or (kout < t_out.shape[0] and t_out[kout] <= t):
                rec = _grow(rec, nrec)
                _record(cfg, geo, mat, law, lawp, t, V0, Vs, F0, y, f0, E, kin, work, rec[nrec], P0)
                if store_states:
                    states = _grow(states, nrec)
                    states[nrec, :] = y
                nrec += 1
                if grid:
                    kout += 1
        if want_energy:
            diagnostics(cfg, geo, mat, law, lawp, V0, Vs, F0, y, f0, kin, work, row, P0)
        while t < tb and status == OK and not done:
            # hn is the step the controller wants; h the one taken (clipped to land on tb)
            h = hn
            if tb - t <= h * (1.0 + 1e-9) or tb - t < 2.0 * hmin:
                h = tb - t
            if nsteps + nrej >= max_steps:
                status = MAX_STEPS
                break
            if interrupt[0] != 0:
                status = INTERRUPTED
                break
            if nrec >= max_rows and not grid:
                status = OUTPUT_FULL
                break
            # the Jacobian is kept across steps while Newton converges fast; it is
            # renewed at every breakpoint, on slow or failed convergence and when the
            # stroke sticks or is released
            jac_fresh = False
            if not jac_ok:
                jacobian(cfg, geo, mat, law, lawp, V0 + Vs * (t - ta), F0 + Fs * (t - ta), y, fbase,
                         Jee, Jeb, Jbe, Jbb, tri, kin, work, tmp, ytmp, jbe)
                if stuck >= 0 or stop != 0:    # the stroke is held: its rows decouple
                    for a in range(Jbb.shape[0]):
                        for b in range(Jbb.shape[1]):
                            if a < nbord or b < nbord:   # (a series resistance's V_d keeps its own)
                                Jbb[a, b] = 0.0
                    Jbe[:, :] = 0.0
                njac += 1
                nfev += 2
                jac_ok = True
                jac_fresh = True
                h_fact = -1.0
                eta = 1.0
            gh = DG * h
            if h != h_fact:
                factor(cfg, mat, gh, Jee, Jeb, Jbe, Jbb, tri, fb, Winv, zeta, cp, dinv, S)
                h_fact = h
            eta = max(eta, 1e-16) ** 0.8
            # ---- stage 1 (trapezoidal rule to t + gamma h), then stage 2 (BDF2 to t + h)
            tg = t + GAMMA * h
            Vg = V0 + Vs * (tg - ta)
            Fg = F0 + Fs * (tg - ta)
            for i in range(n):
                z1[i] = y[i] + GAMMA * h * f0[i]
                base[i] = y[i] + gh * f0[i]
            z1[0] = min(max(z1[0], 0.0), x_e)     # predictors start inside the stops
            held = stuck >= 0 or stop != 0
            conv, its, eta = _newton(cfg, geo, mat, law, lawp, Vg, Fg, z1, base, gh, held, fz, res, dz, y,
                                     scale, rtol, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, kin, work, jbe, eta)
            nfev += its
            slow = its > 2
            ok = conv
            if ok:
                for i in range(n):
                    f1[i] = (z1[i] - base[i]) / gh
                t2 = t + h
                V2 = V0 + Vs * (t2 - ta)
                F2 = F0 + Fs * (t2 - ta)
                for i in range(n):
                    z2[i] = z1[i] + (1.0 - GAMMA) * h * f1[i]
                    base[i] = y[i] + h * WTR * (f0[i] + f1[i])
                z2[0] = min(max(z2[0], 0.0), x_e)
                conv, its, eta = _newton(cfg, geo, mat, law, lawp, V2, F2, z2, base, gh, held, fz, res, dz, y,
                                         scale, rtol, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, kin, work, jbe, eta)
                nfev += its
                slow = slow or its > 2
                ok = conv
            if slow:
                jac_ok = False
            if not ok:
                nrej += 1
                if jac_fresh:
                    hn = 0.25 * h
                else:             # retry with a fresh Jacobian before shrinking the step
                    hn = h
                jac_ok = False
                if hn < hmin:
                    status = STEP_UNDERFLOW
                continue
            for i in range(n):
                f2[i] = (z2[i] - base[i]) / gh
            if held:
                for i in range(nbord):
                    f2[i] = 0.0
            for i in range(n):
                res[i] = h * (E0 * f0[i] + E1 * f1[i] + E2 * f2[i])
            solve(cfg, mat, gh, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, res, err)
            en = _wnorm(err, y, z2, scale, rtol, nbord)
            if not math.isfinite(en):
                nrej += 1
                hn = 0.25 * h
                if hn < hmin:
                    status = NONFINITE
                continue
            if en > 1.0:
                nrej += 1
                hn = h * max(0.2, 0.9 * en ** (-1.0 / 3.0))
                if hn < hmin:
                    status = STEP_UNDERFLOW
                continue
            # ---- stop events: a step ending past a stop, or a held stroke pulled away,
            # is retried to end at the event (linear interpolation of the crossing)
            # event functions: the net zipping force (release), the distance to the stop
            # (impact); a retry when the step ends beyond the tolerance past the event
            event = 0             # 1: impact on a stop, 2: release from it
            g2 = 0.0
            f_near = 0.0
            f_far = 0.0
            retry = False
            if stop != 0:
                g2, gscale = _push(cfg, geo, mat, law, lawp, V2, F2, z2, tmp, kin, work, tri, jbe)
                nfev += 1
                if not _held(stop, g2):
                    event = 2
                    f_near, f_far = g_hold, g2
                    retry = abs(g2) > rtol * gscale
            elif z2[0] < 0.0 or z2[0] > x_e:
                event = 1
                xb = 0.0 if z2[0] < 0.0 else x_e
                f_near, f_far = y[0] - xb, z2[0] - xb
                retry = abs(f_far) > tol_x
            if retry and ev_tries < EV_TRIES and f_near != f_far:
                th, ev_wa, ev_wb, ev_prev = _event_retry(t, h, f_near, f_far, ev_t, ev_wa, ev_wb, ev_prev)
                ev_tries += 1
                nrej += 1
                ev_t = t + h
                hn = h * th
                continue
            # ---- accepted
            nsteps += 1
            if sliding:
                changed = False
                if stuck >= 0:
                    xk = xc[stuck]
                    if _net(cfg, geo, mat, law, lawp, V2, F2, z2, xk - eps_x, tmp, ytmp, kin, work, tri, jbe) <= 0.0:
                        z2[0] = xk - eps_x       # released: moves back (unzips)
                        stuck = -1
                        changed = True
                    elif _net(cfg, geo, mat, law, lawp, V2, F2, z2, xk + eps_x, tmp, ytmp, kin, work, tri, jbe) >= 0.0:
                        z2[0] = xk + eps_x       # released: moves on (zips)
                        stuck = -1
                        changed = True
                elif z2[0] != y[0]:
                    # the first attracting jump passed in the direction of motion
                    up = z2[0] > y[0]
                    lo, hi = (y[0], z2[0]) if up else (z2[0], y[0])
                    ia = np.searchsorted(xc, lo)
                    ib = np.searchsorted(xc, hi)
                    k = ia if up else ib - 1
                    while ia <= k < ib:
                        if _attracting(cfg, geo, mat, law, lawp, V2, F2, z2, xc[k], eps_x, tmp, ytmp, kin, work, tri,
                                       jbe):
                            z2[0] = xc[k]
                            stuck = k
                            changed = True
                            break
                        k += 1 if up else -1
                if changed:
                    jac_ok = False
                    rhs_any(cfg, geo, mat, law, lawp, V2, F2, z2, f2, kin, work, tri, jbe)
                    nfev += 1
                    if stuck >= 0:
                        f2[0] = 0.0
            if event != 0:
                ev_tries = 0
                ev_t = -math.inf
                ev_wa, ev_wb, ev_prev = 1.0, 1.0, 0
            elif ev_t > t + h:    # a trial fell short of the event: the near end moves
                ev_wb = ev_wb * 0.5 if ev_prev == 2 else ev_wb
                ev_wa, ev_prev = 1.0, 2
            if event == 2:        # released: free motion from rest on the stop
                stop = 0
                jac_ok = False
                rhs_any(cfg, geo, mat, law, lawp, V2, F2, z2, f2, kin, work, tri, jbe)
                nfev += 1
            elif event == 1:      # impact (inelastic): on the stop, held if pushed into it
                side = -1 if z2[0] < 0.0 else 1
                z2[0] = 0.0 if side < 0 else x_e
                if nbord == 2 and z2[1] * side > 0.0:
                    if want_energy:
                        E[E_IMPACT] += 0.5 * mat[MASS] * z2[1] * z2[1]
                    z2[1] = 0.0
                g2 = _push(cfg, geo, mat, law, lawp, V2, F2, z2, f2, kin, work, tri, jbe)[0]
                nfev += 1
                stop = side if _held(side, g2) else 0
                if stop != 0:
                    for i in range(nbord):
                        f2[i] = 0.0
                jac_ok = False
            g_hold = g2
            if want_energy:
                Eold[:] = E
                diagnostics(cfg, geo, mat, law, lawp, Vg, Vs, Fg, z1, f1, kin, work, row, P1)
                diagnostics(cfg, geo, mat, law, lawp, V2, Vs, F2, z2, f2, kin, work, row, P2)
                for i in range(NPOW):
                    E[i] += h * (WTR * (P0[i] + P1[i]) + DG * P2[i])
                P0[:] = P2
            if one_step:
                # the step's three nodes (start, stage, end): the caller interpolates them
                rec = _grow(rec, nrec + 2)
                _record(cfg, geo, mat, law, lawp, t, V0 + Vs * (t - ta), Vs, F0 + Fs * (t - ta), y, f0, E, kin, work,
                        rec[nrec], P1)
                _record(cfg, geo, mat, law, lawp, tg, Vg, Vs, Fg, z1, f1, E, kin, work, rec[nrec + 1], P1)
                _record(cfg, geo, mat, law, lawp, t + h, V2, Vs, F2, z2, f2, E, kin, work, rec[nrec + 2], P1)
                nrec += 3
            if grid:
                while kout < t_out.shape[0] and t_out[kout] <= t + h * (1.0 + 1e-12):
                    if interrupt[0] != 0:      # one step can hold many outputs (a long DC hold)
                        status = INTERRUPTED
                        break
                    to = t_out[kout]
                    s = min(1.0, max(0.0, (to - t) / h))
                    for i in range(NPOW):
                        Eint[i] = Eold[i] + s * (E[i] - Eold[i]) if want_energy else 0.0
                    rec = _grow(rec, nrec)
                    _dense_record(cfg, geo, mat, law, lawp, s, h, to, y, z1, z2, V0 + Vs * (to - ta), Vs,
                                  F0 + Fs * (to - ta), Eint, yi, ydi, kin, work, rec[nrec], P1)
                    if store_states:
                        states = _grow(states, nrec)
                        states[nrec, :] = yi
                    nrec += 1
                    kout += 1
            t = t + h
            if tb - t < 2.0 * hmin:
                t = tb
            for i in range(n):
                y[i] = z2[i]
                f0[i] = f2[i]
            if want_trace:
                trace = _grow(trace, ntr)
                trace[ntr, 0] = t
                trace[ntr, 1] = min(max(z1[0], 0.0), x_e)
                trace[ntr, 2] = y[0]
                ntr += 1
            if not grid and not one_step:
                rec = _grow(rec, nrec)
                _record(cfg, geo, mat, law, lawp, t, V2, Vs, F2, y, f0, E, kin, work, rec[nrec], P1)
                if store_states:
                    states = _grow(states, nrec)
                    states[nrec, :] = y
                nrec += 1
            fac = min(5.0, max(0.2, 0.9 * en ** (-1.0 / 3.0) if en > 0 else 5.0))
            hn = h * fac if h >= hn else max(hn, h * fac)
            if after_jump:
                h_jump = hn
                after_jump = False
            if ev_t > t:          # a located stop event still ahead: stay inside its bracket
                hn = min(hn, ev_t - t)
            if one_step:
                done = True
        if status != OK:
            break
        # what the next call continues from (f0 belongs to V, F at the segment end)
        for i in range(n):
            fkeep[i] = f0[i]
        ist[I_F] = F0 + Fs * (t - ta)
        ist[I_F0OK] = 1.0 if Vs == 0.0 and Fs == 0.0 else 0.0
        if done:
            break
    ist[I_JOK] = 1.0 if jac_ok else 0.0
    ist[I_HFACT] = h_fact
    ist[I_ETA] = eta
    ist[I_HN] = hn
    ist[I_STUCK] = stuck
    ist[I_STOP] = stop
    ist[I_GHOLD] = g_hold
    ist[I_HJUMP] = h_jump
    ist[I_AFTERJ] = 1.0 if after_jump else 0.0
    if status == INTERRUPTED:     # abandoned: no copies of what was recorded (a long run's are large)
        nrec = 0
        ntr = 0
    stats = np.array([nsteps, nrej, nfev, njac, status, t], dtype=np.float64)
    return (rec[:nrec].copy(), states[:nrec].copy() if store_states else states[:0].copy(), stats, y,
            trace[:ntr].copy())
