"""Events of the stroke in the TR-BDF2 integrator (integrator.py): the stops at both ends
of the stroke and the force jumps where it sticks (a sliding point).

Stops: the stroke lies in [0, x_e]. A step that ends past a stop is retried to end there
(regula falsi with the Illinois rule, at most EV_TRIES times); on the stop the motion is
held (inelastic impact: the kinetic energy is booked) while the net force pushes into it,
and released when it no longer does (located the same way, on the net force).

Force jumps (the paper scheme's midpoint crossings): there the stroke equation has a
discontinuous right-hand side and the equilibrium is a sliding point; the stroke sticks
at a crossing while the force pushes towards it from both sides and is released when it
no longer does.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..physics.equations import C_NBORD, K, MASS, X_E
from .kernels import rhs_b
from .trbdf2 import (EV_PREV, EV_T, EV_WA, EV_WB, G_E, I_GHOLD, I_JOK, I_STOP, I_STUCK, N_EVTRIES, N_FEV, N_REJ, W_F2,
                    W_TMP, W_YTMP, W_Z2)
from .stepping import to_stop

# impact energy slot of the energy accumulators (equations.NPOW)
E_IMPACT = 6
# a stop event (impact, release) is located by at most this many retried steps
EV_TRIES = 6


@njit(cache=True, _nrt=False)
def net_rate(M, wk, V, F, y, x, tmp, ytmp):
    """Stroke rate dx/dt with the stroke set to x (other states as in y)."""
    for i in range(y.shape[0]):
        ytmp[i] = y[i]
    ytmp[0] = x
    rhs_b(M, wk, V, F, ytmp, tmp)
    return tmp[0]


@njit(cache=True, _nrt=False)
def attracting(M, wk, V, F, y, xk, eps, tmp, ytmp):
    """Whether the force jump at xk pulls the stroke in from both sides."""
    return (net_rate(M, wk, V, F, y, xk - eps, tmp, ytmp) > 0.0 and
            net_rate(M, wk, V, F, y, xk + eps, tmp, ytmp) < 0.0)


@njit(cache=True, _nrt=False)
def push(M, wk, V, F, y, ydot):
    """Net force towards zipping at state y, -(F + k x + F_e) (N), and its scale
    |F| + |k x| + |F_e| (for a tolerance); ydot receives f(y)."""
    mat = M[2]
    Fe = rhs_b(M, wk, V, F, y, ydot)
    return -(F + mat[K] * y[0] + Fe), abs(F) + abs(mat[K] * y[0]) + abs(Fe)


@njit(cache=True, _nrt=False)
def touching(y, nbord, x_e):
    """The stop the state touches, moving into it or at rest: -1 (x = 0), +1 (x_e), 0."""
    if y[0] <= 0.0 and (nbord == 1 or y[1] <= 0.0):
        return -1
    if y[0] >= x_e and (nbord == 1 or y[1] >= 0.0):
        return 1
    return 0


@njit(cache=True, _nrt=False)
def held(stop, g):
    """Whether a stroke on `stop` stays there under the net zipping force g."""
    return (stop < 0 and g <= 0.0) or (stop > 0 and g >= 0.0)


@njit(cache=True, _nrt=False)
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


@njit(cache=True, _nrt=False)
def stop_event(M, wk, ist, cnt, ev, w, y, t, h, V2, F2, rtol, tol_x):
    """Whether the step [t, t + h] from y to w[W_Z2] meets a stop event: an impact (the
    stroke ends past a stop, event function the distance to it) or a release (a held
    stroke's net force no longer pushes into its stop). Returns (event: 0 none, 1 impact,
    2 release; the net zipping force at the end (release checks); the fraction of the step
    to retry with, 0 to accept it)."""
    z2, tmp = w[W_Z2], w[W_TMP]
    stop = int(ist[I_STOP])
    event = 0
    g2 = 0.0
    f_near = 0.0
    f_far = 0.0
    retry = False
    if stop != 0:
        g2, gscale = push(M, wk, V2, F2, z2, tmp)
        cnt[N_FEV] += 1
        if not held(stop, g2):
            event = 2
            f_near, f_far = ist[I_GHOLD], g2
            retry = abs(g2) > rtol * gscale
    else:
        f_near, f_far, side = to_stop(y[0], z2[0], M[2][X_E])
        if side != 0:
            event = 1
            retry = abs(f_far) > tol_x
    if retry and cnt[N_EVTRIES] < EV_TRIES and f_near != f_far:
        th, ev[EV_WA], ev[EV_WB], ev[EV_PREV] = _event_retry(t, h, f_near, f_far, ev[EV_T], ev[EV_WA], ev[EV_WB],
                                                             ev[EV_PREV])
        cnt[N_EVTRIES] += 1
        cnt[N_REJ] += 1
        ev[EV_T] = t + h
        return event, g2, th
    return event, g2, 0.0


@njit(cache=True, _nrt=False)
def settle_event(M, wk, ist, cnt, ev, w, event, g2, t, h, V2, F2, want_energy, eg):
    """After an accepted step: close the event bracket, release the stroke from its stop
    or put it on the stop it hit (inelastic impact, kinetic energy booked; held there if
    pushed into it)."""
    cfg, mat = M[0], M[2]
    nbord = cfg[C_NBORD]
    z2, f2 = w[W_Z2], w[W_F2]
    if event != 0:
        cnt[N_EVTRIES] = 0
        ev[EV_T], ev[EV_WA], ev[EV_WB], ev[EV_PREV] = -math.inf, 1.0, 1.0, 0.0
    elif ev[EV_T] > t + h:    # a trial fell short of the event: the near end moves
        ev[EV_WB] = ev[EV_WB] * 0.5 if ev[EV_PREV] == 2 else ev[EV_WB]
        ev[EV_WA], ev[EV_PREV] = 1.0, 2.0
    if event == 2:            # released: free motion from rest on the stop
        ist[I_STOP] = 0.0
        ist[I_JOK] = 0.0
        rhs_b(M, wk, V2, F2, z2, f2)
        cnt[N_FEV] += 1
    elif event == 1:          # impact (inelastic): on the stop, held if pushed into it
        side = -1 if z2[0] < 0.0 else 1
        z2[0] = 0.0 if side < 0 else mat[X_E]
        if nbord == 2 and z2[1] * side > 0.0:
            if want_energy:
                eg[G_E, E_IMPACT] += 0.5 * mat[MASS] * z2[1] * z2[1]
            z2[1] = 0.0
        g2 = push(M, wk, V2, F2, z2, f2)[0]
        cnt[N_FEV] += 1
        stop = side if held(side, g2) else 0
        ist[I_STOP] = stop
        if stop != 0:
            for i in range(nbord):
                f2[i] = 0.0
        ist[I_JOK] = 0.0
    ist[I_GHOLD] = g2


@njit(cache=True, _nrt=False)
def sliding_point(M, wk, ist, cnt, w, y, xc, eps_x, V2, F2):
    """After an accepted step of the paper scheme: a stuck stroke is released when a
    side no longer pulls it in; a moving one sticks at the first attracting force jump it
    passed."""
    z2, f2, tmp, ytmp = w[W_Z2], w[W_F2], w[W_TMP], w[W_YTMP]
    stuck = int(ist[I_STUCK])
    changed = False
    if stuck >= 0:
        xk = xc[stuck]
        if net_rate(M, wk, V2, F2, z2, xk - eps_x, tmp, ytmp) <= 0.0:
            z2[0] = xk - eps_x       # released: moves back (unzips)
            stuck = -1
            changed = True
        elif net_rate(M, wk, V2, F2, z2, xk + eps_x, tmp, ytmp) >= 0.0:
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
            if attracting(M, wk, V2, F2, z2, xc[k], eps_x, tmp, ytmp):
                z2[0] = xc[k]
                stuck = k
                changed = True
                break
            k += 1 if up else -1
    if changed:
        ist[I_STUCK] = stuck
        ist[I_JOK] = 0.0
        rhs_b(M, wk, V2, F2, z2, f2)
        cnt[N_FEV] += 1
        if stuck >= 0:
            f2[0] = 0.0
