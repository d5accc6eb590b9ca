"""What the TR-BDF2 integrator (integrator.py) records of an accepted step: the energy
balance's increments, the output rows (every step, or the caller's output times by dense
output) and the stroke trace the metrics are computed from."""
from __future__ import annotations

from .._jit import njit
from ..physics.equations import NPOW, R_EIN, R_T, R_X, X_E
from .kernels import diagnostics_b
from .trbdf2 import (DG, G_E, G_EINT, G_EOLD, G_P0, G_P1, G_P2, GAMMA, INTERRUPTED, N_OUT, N_REC, W_F0, W_F1, W_F2,
                     W_YDI, W_YI, W_Z1, W_Z2, WTR)
from .stepping import grow



@njit(cache=True, _nrt=False)
def record(M, wk, t, V, dVdt, F, y, ydot, E, row, P):
    """One output row at time t, state y."""
    row[:] = 0.0
    diagnostics_b(M, wk, V, dVdt, F, y, ydot, row, P)
    row[R_T] = t
    row[R_X] = y[0]
    for i in range(NPOW):
        row[R_EIN + i] = E[i]


@njit(cache=True, _nrt=False)
def dense_record(M, wk, s, h, to, y, z1, z2, V, Vs, F, E, yi, ydi, row, P):
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
    yi[0] = min(max(yi[0], 0.0), M[2][X_E])     # the interpolant's overshoot past a stop
    if y[0] == z1[0] and z1[0] == z2[0]:       # held (a stop, a sliding point): exactly
        yi[0] = y[0]
        ydi[0] = 0.0
    record(M, wk, to, V, Vs, F, yi, ydi, E, row, P)


@njit(cache=True, _nrt=False)
def energy_step(M, wk, w, eg, row, h, Vg, Fg, V2, F2, Vs):
    """Add the step's energy increments: the powers at the stage and the end, weighted
    as TR-BDF2 weights its stages (the start's powers are the last step's end's)."""
    E, Eold, P0, P1, P2 = eg[G_E], eg[G_EOLD], eg[G_P0], eg[G_P1], eg[G_P2]
    diagnostics_b(M, wk, Vg, Vs, Fg, w[W_Z1], w[W_F1], row, P1)
    diagnostics_b(M, wk, V2, Vs, F2, w[W_Z2], w[W_F2], row, P2)
    for i in range(NPOW):
        Eold[i] = E[i]
        E[i] += h * (WTR * (P0[i] + P1[i]) + DG * P2[i])
        P0[i] = P2[i]


@njit(cache=True, inline="always")
def step_nodes(M, wk, w, eg, y, t, h, ta, V0, Vs, F0, Fs, Vg, Fg, V2, F2, rec, cnt):
    """one_step: the step's three nodes (start, stage, end), which the caller
    interpolates (dfa_model.numerics.stepper)."""
    nrec = cnt[N_REC]
    E, P1 = eg[G_E], eg[G_P1]
    tg = t + GAMMA * h
    rec = grow(rec, nrec + 2)
    record(M, wk, t, V0 + Vs * (t - ta), Vs, F0 + Fs * (t - ta), y, w[W_F0], E, rec[nrec], P1)
    record(M, wk, tg, Vg, Vs, Fg, w[W_Z1], w[W_F1], E, rec[nrec + 1], P1)
    record(M, wk, t + h, V2, Vs, F2, w[W_Z2], w[W_F2], E, rec[nrec + 2], P1)
    cnt[N_REC] = nrec + 3
    return rec


@njit(cache=True, inline="always")
def dense_outputs(M, wk, w, eg, y, t, h, ta, V0, Vs, F0, Fs, t_out, want_energy, store_states, rec, states, cnt,
                  interrupt):
    """The output times within the step [t, t + h]: rows by dense output. Returns the
    (grown) records and OK, or INTERRUPTED (one step can hold many outputs: a long DC
    hold)."""
    E, Eold, Eint, P1 = eg[G_E], eg[G_EOLD], eg[G_EINT], eg[G_P1]
    yi = w[W_YI]
    while cnt[N_OUT] < t_out.shape[0] and t_out[cnt[N_OUT]] <= t + h * (1.0 + 1e-12):
        if interrupt[0] != 0:
            return rec, states, INTERRUPTED
        nrec = cnt[N_REC]
        to = t_out[cnt[N_OUT]]
        s = min(1.0, max(0.0, (to - t) / h))
        for i in range(NPOW):
            Eint[i] = Eold[i] + s * (E[i] - Eold[i]) if want_energy else 0.0
        rec = grow(rec, nrec)
        dense_record(M, wk, s, h, to, y, w[W_Z1], w[W_Z2], V0 + Vs * (to - ta), Vs, F0 + Fs * (to - ta), Eint, yi,
                     w[W_YDI], rec[nrec], P1)
        if store_states:
            states = grow(states, nrec)
            states[nrec, :] = yi
        cnt[N_REC] = nrec + 1
        cnt[N_OUT] += 1
    return rec, states, 0
