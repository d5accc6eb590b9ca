"""The compiled integrator of the low-order surrogates (reduced/): a stroke, the front
layer that carries the force, and a few material points that carry the charge history.

Why this shape (README, 'Surrogates'): the interface charge belongs to the material. The
force acts through the material just beyond the zipping front, whose response the front
layer reproduces (its rates moment-matched to the full model's force-weighted charge at
each frozen stroke, reduced/frozen.py); but when the front moves, the layer is renewed
by the material it moves onto, and that material's charge depends on its history (zipped
at a voltage step ten seconds ago, or never). A few material points spread over the
electrode keep that history. Between them and the layer, a wake on each side of the
front: the zipped material just behind the layer and the unzipped material just ahead,
each a band c_w w_f wide. A front that moves renews the layer from the wake it moves
into, that wake from the material beyond it (ahead: the first unzipped point; behind:
the zipped material a wake width back, interpolated between the points), and the other
wake from the layer it leaves: a front that turns back finds the material it just
swept, not a point millimetres away (one uniform zipped charge, as before, renewed a
retreating front with material zipped long ago; renewing the layer from the points
directly locked a front that turned back into running away from the charge it had just
left). One exception: a retreating front renews the ahead wake's polarization from the
behind wake's, not from the layer's. The material it releases carries its zipped P
(tau_p ~ 1 s: it is still there a few tenths of a millimetre out), and the branch's
force sits right there, over the ahead wake's band (frozen.polarization_weights). The
layer is force-weighted for the charge: its P is already partly relaxed, and the ahead
wake filled from it made the branch's force 30 % low in a DC creep on Table 1
(0.23 against 0.33 N; 0.31 now), the creep 6-17 % too fast.

Every charge state is a material point with pointwise physics, the full model's own
(dfa_model.physics.nodal): for an inverse gap 1/u and a screening thickness T0',

    sigma_l = (eps_l V_d - T0' q) / u,   J_l = law(sigma_l / eps_l) (equations.j_of_E),
    dP/dt   = (chi_p sigma_l - P) / tau_p                (polarization branch),
    dq/dt   = J_l - (sigma_l + q) / tau_f + dP/dt,

q the charge the electrostatics see (q' of the nodal scheme). Material points sit at
their own gap (a column per point); the front layer is an effective point whose gap and
T0' reproduce its moment-matched rates (frozen.front_layer). The force is the full
model's quadratic map of the layer's (V, q, P); behind a series resistance R_s the device
voltage V_d is a state: C(x) dV_d/dt = (V - V_d)/R_s - (its motion and charge currents).

State y (NY = NODE0 + 2 n + 2; a state the actuator does not have stays 0):

    X, VEL, VD, QF, PF      stroke, velocity (a mass), V_d (R_s), layer charge and polarization
    QB, PB, QA, PA          the wakes: the zipped material just behind the layer and the
                            unzipped material just ahead of it (charge, polarization)
    SM                      a memory, not a rate: the anchor a of a play operator, the
                            layer's material lagging the front by s = a + l_z(x) (m of
                            zipped length), clipped to the lag c_m w_f (par P_DM = c_m)
                            plus a band; renewed after each accepted step (_replay), its
                            rate 0. Within the lag the front's motion does not mix the
                            wakes into the layer (its advection kept at par P_ADV =
                            c_adv)
    NODE0 + i               material point i's charge, i < n (at s_i = i l_e / (n - 1))
    NODE0 + n + i           its polarization
    NY - 2, NY - 1          the inputs V and F, states with a constant slope on each segment

Steps: the Rosenbrock-W pair of Shampine's ode23s (L-stable, order 2, error at order 3),
restarted at every input breakpoint; in the lattice form without a mass a step of at least
ROS_SWITCH of the stroke's time constants takes ROS34PW2 instead (_stages_ros34: order 3,
stiffly accurate; the standard protocol's 20 s creep took 57 ode23s tries, 22 of them
rejected, then about 30 with it, 20 of them accepted, and about 20, 18 accepted, with the
steps sized from the stroke's balance too: OFF_ORDER), a step crosses at most LAT_CELLS of
the tables' grid intervals, and the steps after landing on a stop resume at the size they
had before the landing; the stops at 0 and x_e are events; a step moves the
stroke by at most DX_STEP x_e, and without a mass a step that leaves the stroke off its
balance by more than the tolerance after passing it, or after RELAX of its time constants,
is rejected (the pair's error estimate fades as a step outgrows the mechanics' time
constant), and the next step is sized from that distance too (OFF_ORDER). The Jacobian:
forward differences in the core states (stroke, velocity, V_d, layer, inputs) and the
points' own 2 x 2 blocks in closed form; the linear solves eliminate the points' blocks
onto the core (the points couple only to the stroke, V_d and, through the renewal, the
layer), so a step costs O(n). After a polarity inversion the core columns are taken from
the previous half period's, mirrored (integrate: JAC_TOL), which saves a third of the time
of a square wave.
"""
from __future__ import annotations

import math

import numpy as np

from .._jit import njit
from ..physics.equations import j_and_slope, j_of_E
from .stepping import GROW_MAX, grow_factor, shrink_factor, to_stop, worst

# state indices
X, VEL, VD, QF, PF, QB, PB, QA, PA, SM = range(10)
NODE0 = 10
NCORE = 12         # X .. SM and the inputs V, F (at NY - 2, NY - 1)
# table columns (per stroke grid point); the material points' inverse gaps follow
C0, C1, C2, PAA, IUF, T0F, WF, DLZ, LZ, CAP, I0, I1, J0, J1, IUA = range(15)
NFIX = 15
LAG_BAND = 1.0    # the renewal sets in over this many material lags beyond the lag
# parameters
(P_XE, P_B, P_M, P_K, P_RS, P_CHI, P_TAUP, P_TAUF, P_EPSL, P_T0, P_ICELL, P_AVG, P_N, P_LE, P_ITAUL,
 P_CONST, P_IWB, P_IU0, P_VS, P_DM, P_ADV, P_LAT) = range(22)
NPAR = 22
# the lattice form (par P_LAT > 0; module docstring): per lattice point i its columns at
# lat0(n) + k n + i, k = LAT_C1 .. LAT_JQ: the force's V q_i weight, its q_i^2 and
# q_i q_(i+1) weights, and the source current's conduction and motion weights of q_i
LAT_C1, LAT_C2, LAT_C2O, LAT_IQ, LAT_JQ = range(5)
NLAT = 5
# the rows' last entry, one past the tables' columns (rw: tab.shape[1] + 1 entries): the
# lattice form's first point with force weights (lattice_row; the ones before are zipped
# over the whole stencil and their weights are exact zeros)
# record columns
R_T, R_X, R_V, R_QF, R_PF, R_VD, R_VOLT, R_F, R_I, R_FE = range(10)
NREC = 10
# status
OK, FULL, MAX_STEPS, NONFINITE = 0, 1, 2, 3
FREE, HELD, AUTO = 0, 1, 2
# Jacobian reuse in integrate (across inversions): the largest relative state change
# from the mirrored state it was taken at, and the most half periods in a row
JAC_TOL = 0.02
JAC_USES = 50
# the most an accepted step moves the stroke, as a share of x_e (_integrate)
DX_STEP = 0.2
# a step's first try moves the stroke at its start's rate by at most this share of that
# (_integrate): after a switch the step carried over from before it was tried and cut
# 3-7 times (7 of a unipolar train's 33 tries a period, at the switch on)
DX_FIRST = 0.7
# a step landed on a stop within this share of its travel ends on it (_snap)
LAND_SHARE = 1e-3
# the most a step held on a stop may grow after an accepted one (GROW_MAX elsewhere)
GROW_HELD = 50.0
# a step (no mass) of this many of the stroke's time constants ends at its balance (_integrate)
RELAX = 20.0
# the lattice form: a step (no mass) of at least RELAX time constants ends off the balance
# by a share of the tolerance that grows as about its length to the OFF_ORDER: the next
# step is at most OFF_SAFETY h off^(-1 / OFF_ORDER) (_off_bound). Measured in the standard
# protocol's creep (ROS34PW2): 0.9 -> 2.0 s took it from 0.4 to 15-20 um (h^4.6); the error
# estimate let the steps grow to 2 s, and 12 of its 30 tries were rejected for it. Not in
# the charge family (ode23s): there the rejections had kept the steps short, and without
# them a Peano creep took 2.5 s steps past a front's jump (held-out RMS 0.37 -> 1.38 %)
OFF_ORDER = 4.0
OFF_SAFETY = 0.8
# the lattice form without a mass: a step of at least this many of the stroke's time constants
# is taken with ROS34PW2 (_stages_ros34), a shorter one with ode23s (_stages); and a step moves
# the stroke across at most LAT_CELLS of the tables' grid intervals (_integrate)
ROS_SWITCH = 5.0
LAT_CELLS = 32.0
# ROS34PW2 (Rang & Angermann, BIT 45 (2005) 761-787: 4 stages, order 3, embedded order 2,
# L-stable and stiffly accurate) in Hairer & Wanner's transformed form (IV.7):
# (I - h gam J) k_i = gam (f(y + h sum_j A_ij k_j) + sum_j C_ij k_j), y1 = y + h sum_i M_i k_i,
# the error h sum_i E_i k_i; A = alpha G^-1, C = diag(1/gam) - G^-1, M = b G^-1, E = (b - b^) G^-1
# from the paper's alpha, G (gamma_ij) and b, b^ (tests/test_ros34.py recomputes them)
R_GAM = 0.43586652150845900
R_A21 = 2.0
R_A31, R_A32 = 1.4192173174557652, -0.25923221167296978
R_A41, R_A42, R_A43 = 4.1847604823191613, -0.28519201735549599, 2.2942803602790423
R_C21 = -4.5885607205580836
R_C31, R_C32 = -4.1847604823191613, 0.28519201735549599
R_C41, R_C42, R_C43 = -6.3681792001283597, -6.7956209444668367, 2.8700986043310555
R_M1, R_M2, R_M3, R_M4 = 4.184760482319162, -0.2851920173554956, 2.294280360279042, 1.0
R_E1, R_E2, R_E3, R_E4 = 0.277749947647969, -1.4032398951759988, 1.7726301276675507, 0.5
# the kept Jacobian's record in integrate (js): taken at this step (not for reuse), times
# reused in a row, number of active core columns, the input voltage it was taken at, and
# whether it is kept across integrate's calls at a nearby voltage too (pi_loop)
J_FRESH, J_USES, J_M, J_V, J_NEAR = range(5)
WS_JS = 27        # js's place in _workspace's tuple


@njit(cache=True, _nrt=False, inline="always")
def _cell(tab, xe, x):
    """(i, f): the grid interval [i, i + 1] of stroke x (clamped to [0, x_e]) and the
    fraction f into it."""
    n = tab.shape[0]
    u = min(max(x, 0.0), xe) / xe * (n - 1)
    # a NaN stroke (a non-finite state: evaluate's, a diverged stage's) gives NaN values
    # from interval 0; int(NaN) is -2^63, an unchecked index far outside the table
    i = int(u) if u == u else 0
    if i > n - 2:
        i = n - 2
    return i, u - i


@njit(cache=True, _nrt=False, inline="always")
def _hermite(tab, i, c, f):
    """Column c's cubic Hermite with centred slopes (per grid step) at fraction f of
    interval i."""
    n = tab.shape[0]
    f2 = f * f
    f3 = f2 * f
    a, b = tab[i, c], tab[i + 1, c]
    ma = 0.5 * (b - tab[i - 1, c]) if i > 0 else b - a
    mb = 0.5 * (tab[i + 2, c] - a) if i + 2 < n else b - a
    return (2.0 * f3 - 3.0 * f2 + 1.0) * a + (f3 - 2.0 * f2 + f) * ma + (-2.0 * f3 + 3.0 * f2) * b + (f3 - f2) * mb


@njit(cache=True, _nrt=False)
def table_row(tab, xe, x, rw):
    """The maps at stroke x (clamped to [0, x_e]): cubic Hermite with centred slopes, so
    that the force and the renewal (the front's lever and the layer's width) have
    continuous slopes in x: with linear pieces they jumped at every grid point, and a
    Rosenbrock stage a few micrometres off the step's start saw the stiff mechanics
    answer that jump (the error estimate grew by up to 1000 during a slow creep). The
    material points' gaps, which enter only their own slow rates, are linear."""
    i, f = _cell(tab, xe, x)
    for c in range(NFIX):
        rw[c] = _hermite(tab, i, c, f)
    # the material points' gaps enter only their own (slow) rates: linear pieces do
    for k in range(tab.shape[1] - NFIX):
        c = np.uint64(NFIX + k)       # unsigned: vectorized without gathers (_blend)
        rw[c] = tab[i, c] * (1.0 - f) + tab[i + 1, c] * f


@njit(cache=True, _nrt=False, inline="always")
def _blend(tab, rw, r0, r1, r2, r3, w0, w1, w2, w3, c0, c1):
    """rw[c] = w0 tab[r0, c] + w1 tab[r1, c] + w2 tab[r2, c] + w3 tab[r3, c] for c in
    [c0, c1): one interpolation's weights for many columns (a branch-free loop). The
    column index is unsigned: a signed one is wrapped around when negative, and that
    select made LLVM vectorize the loop with gathers and scatters (6x slower)."""
    for k in range(c1 - c0):
        c = np.uint64(c0 + k)
        rw[c] = w0 * tab[r0, c] + w1 * tab[r1, c] + w2 * tab[r2, c] + w3 * tab[r3, c]


@njit(cache=True, _nrt=False)
def lattice_row(tab, xe, x, rw, n, le, pol, cur):
    """table_row for the lattice form: the force's weights (the points' charges' and
    polarizations') cubic Hermite like the fixed columns (the force's slope in x must
    not jump at the grid points: linear pieces there took 2.5x the steps), the gaps and
    the current's weights linear; a point whose hat is zipped over the whole Hermite
    stencil has no force weights (exact zeros in the tables), so only the unzipped
    points are interpolated; their first, k0, goes into the row's last entry. cur: also
    the current's weights (else left as they are: only the record and V_d's equation read
    them, _lattice_current). The cubic Hermite with centred slopes is a fixed blend of the
    rows i - 1 .. i + 2, its weights computed once for all columns."""
    i, f = _cell(tab, xe, x)
    for c in range(NFIX):
        rw[c] = _hermite(tab, i, c, f)
    ng = tab.shape[0]
    g = 1.0 - f
    _blend(tab, rw, i, i + 1, i, i + 1, g, f, 0.0, 0.0, NFIX, NFIX + n)
    # Hermite: h00 a + h10 ma + h01 b + h11 mb, ma = (b - p) / 2 (b - a at the first
    # interval), mb = (nx - a) / 2 (b - a at the last)
    f2 = f * f
    f3 = f2 * f
    h00, h10, h01, h11 = 2.0 * f3 - 3.0 * f2 + 1.0, f3 - 2.0 * f2 + f, -2.0 * f3 + 3.0 * f2, f3 - f2
    wp, wa, wb, wn = 0.0, h00, h01, 0.0
    rp, rn = i, i + 1
    if i > 0:
        rp = i - 1
        wp -= 0.5 * h10
        wb += 0.5 * h10
    else:
        wa -= h10
        wb += h10
    if i + 2 < ng:
        rn = i + 2
        wn += 0.5 * h11
        wa -= 0.5 * h11
    else:
        wb += h11
        wa -= h11
    # zipped over the stencil: s_(k+1) <= l_z at its least stroke (row rp)
    k0 = min(int(tab[rp, LZ] / (le / (n - 1))), n)
    rw[rw.shape[0] - 1] = k0
    o = lat0(n)
    for base in (NFIX + n, NFIX + 2 * n, o + LAT_C1 * n, o + LAT_C2 * n, o + LAT_C2O * n):
        if base < o and not pol:
            continue          # no polarization branch: its weights are never read
        for k in range(k0):
            rw[np.uint64(base + k)] = 0.0
        _blend(tab, rw, rp, i, i + 1, rn, wp, wa, wb, wn, base + k0, base + n)
    if cur:
        _current_weights(tab, rw, i, f, n)


@njit(cache=True, _nrt=False, inline="always")
def _current_weights(tab, rw, i, f, n):
    """The lattice form's current weights (conduction and motion of each point's charge),
    linear at fraction f of grid interval i."""
    o = lat0(n)
    _blend(tab, rw, i, i + 1, i, i + 1, 1.0 - f, f, 0.0, 0.0, o + LAT_IQ * n, o + (LAT_JQ + 1) * n)


@njit(cache=True, _nrt=False, inline="always")
def table_value(tab, xe, x, c):
    """One column c < NFIX of table_row at stroke x."""
    i, f = _cell(tab, xe, x)
    return _hermite(tab, i, c, f)


@njit(cache=True, _nrt=False, inline="always")
def _point(par, law, lawp, Vd, W, q, P, iu, t0p, out):
    """A material point's rates: out = [dq/dt, dP/dt, d(dq)/dq, d(dq)/dP, d(dP)/dq, d(dP)/dP]."""
    eps_l, itf = par[P_EPSL], 1.0 / par[P_TAUF]
    sl = (eps_l * Vd - t0p * q) * iu
    if par[P_CONST] != 0.0:
        dJ = par[P_ITAUL]
        Jl = sl * dJ
    elif par[P_AVG] > 0.0 and W >= 0.0:
        # averaged mode: the law's conductance at the drive's RMS field (the field's sign
        # alternates within a period; its magnitude is what the law sees)
        E = math.sqrt(W) * iu
        hE = 1e-6 * abs(E) + 1e-3
        dJ = j_of_E(law, lawp, E) / (E * eps_l) if E > hE else \
            (j_of_E(law, lawp, hE) - j_of_E(law, lawp, -hE)) / (2.0 * hE * eps_l)
        Jl = sl * dJ
    else:
        Jl, dJ = j_and_slope(law, lawp, sl / eps_l, eps_l)
    g = Jl - (sl + q) * itf
    t0u = t0p * iu
    dg = -dJ * t0u - (1.0 - t0u) * itf
    chi = par[P_CHI]
    if chi > 0.0:
        itp = 1.0 / par[P_TAUP]
        Pd = (chi * sl - P) * itp
        out[0] = g + Pd
        out[1] = Pd
        out[2] = dg - chi * t0u * itp
        out[3] = -itp
        out[4] = -chi * t0u * itp
        out[5] = -itp
    else:
        out[0] = g
        out[1] = 0.0
        out[2] = dg
        out[3] = 0.0
        out[4] = 0.0
        out[5] = 0.0


@njit(cache=True, _nrt=False, inline="always")
def _zipped_mean(y, rw, par, n):
    """The mean charge of the zipped material points (the layer's without any; 0 in the
    lattice form, whose current does not read it)."""
    if par[P_LAT] > 0.0:
        return 0.0
    h = par[P_LE] / (n - 1) if n > 1 else 0.0
    qz = 0.0
    nz = 0
    lz = rw[LZ]
    for i in range(n):
        if i * h > lz:          # the points lie in order along the electrode: the rest are unzipped
            break
        qz += y[NODE0 + i]
        nz += 1
    return qz / nz if nz > 0 else y[QF]


@njit(cache=True, _nrt=False, inline="always")
def _points(y, W, par, law, lawp, ydot, rw, pt, jn, n, NY):
    """The material points' rates into ydot (their 2 x 2 blocks into jn when jn has rows)
    at the maps' row rw; returns the zipped points' mean charge (the conduction current)."""
    Vd = y[VD] if par[P_RS] > 0.0 else y[NY - 2]
    t0 = par[P_T0]
    store = jn.shape[0] >= n
    if par[P_CONST] != 0.0 and par[P_CHI] == 0.0:
        # the common case in a tight loop: dq/dt = c (eps_l V - T0 q) / u - q / tau_f
        itf = 1.0 / par[P_TAUF]
        c = par[P_ITAUL] - itf
        ceV = c * par[P_EPSL] * Vd
        cT0 = c * t0
        # unsigned indices: numba's wrap-around of negative ones drops out, the loop
        # vectorizes (_blend)
        for k in range(n):
            i = np.uint64(k)
            iu = rw[NFIX + i]
            a = -(cT0 * iu + itf)
            ydot[NODE0 + i] = ceV * iu + a * y[NODE0 + i]
            ydot[NODE0 + n + i] = 0.0
            if store:
                jn[i, 0], jn[i, 1], jn[i, 2], jn[i, 3] = a, 0.0, 0.0, 0.0
        return _zipped_mean(y, rw, par, n)
    for i in range(n):
        _point(par, law, lawp, Vd, W, y[NODE0 + i], y[NODE0 + n + i], rw[NFIX + i], t0, pt)
        ydot[NODE0 + i] = pt[0]
        ydot[NODE0 + n + i] = pt[1]
        if store:
            jn[i, 0], jn[i, 1], jn[i, 2], jn[i, 3] = pt[2], pt[3], pt[4], pt[5]
    return _zipped_mean(y, rw, par, n)


@njit(cache=True, _nrt=False, inline="always")
def _polarization_force(y, rw, n):
    """The branch's force over the unzipped length (frozen.polarization_weights): the
    ahead wake's band and P u linear between the material points."""
    Fp = rw[PAA] * y[PA] * y[PA]
    d0, o0 = NFIX + n, NFIX + 2 * n
    for i in range(n):
        Pi = y[NODE0 + n + i]
        Fp += rw[d0 + i] * Pi * Pi
        if i + 1 < n:
            Fp += 2.0 * rw[o0 + i] * Pi * y[NODE0 + n + i + 1]
    return Fp


@njit(cache=True, _nrt=False, inline="always")
def _polarization_slopes(y, rw, n, rate, cp):
    """d(force)/dP_i, times `rate` (the stroke's or velocity's answer to the force), into cp."""
    d0, o0 = NFIX + n, NFIX + 2 * n
    for i in range(n):
        v = 2.0 * rw[d0 + i] * y[NODE0 + n + i]
        if i + 1 < n:
            v += 2.0 * rw[o0 + i] * y[NODE0 + n + i + 1]
        if i > 0:
            v += 2.0 * rw[o0 + i - 1] * y[NODE0 + n + i - 1]
        cp[i] = rate * v


@njit(cache=True, _nrt=False, inline="always")
def lat0(n):
    """The first lattice column: after the points' inverse gaps and their P weights."""
    return NFIX + 3 * n


@njit(cache=True, _nrt=False, inline="always")
def _charge_force(y, rw, n, Vd):
    """The lattice form's force from the points' charges: V q_i, q_i^2 and q_i q_(i+1)
    weights (the full model's quadratic map read off at each stroke, frozen.lattice_tables)."""
    o = lat0(n)
    F = 0.0
    # from the first point with weights (lattice_row's k0: the others add exact zeros)
    for i in range(int(rw[rw.shape[0] - 1]), n):
        q = y[NODE0 + i]
        F += q * (rw[o + LAT_C1 * n + i] * Vd + rw[o + LAT_C2 * n + i] * q)
        if i + 1 < n:
            F += 2.0 * rw[o + LAT_C2O * n + i] * q * y[NODE0 + i + 1]
    return F


@njit(cache=True, _nrt=False, inline="always")
def _charge_slopes(y, rw, n, Vd, rate, cq):
    """d(force)/dq_i of _charge_force, times `rate` (the stroke's or velocity's answer to
    the force), into cq."""
    o = lat0(n)
    for i in range(n):
        v = rw[o + LAT_C1 * n + i] * Vd + 2.0 * rw[o + LAT_C2 * n + i] * y[NODE0 + i]
        if i + 1 < n:
            v += 2.0 * rw[o + LAT_C2O * n + i] * y[NODE0 + i + 1]
        if i > 0:
            v += 2.0 * rw[o + LAT_C2O * n + i - 1] * y[NODE0 + i - 1]
        cq[i] = rate * v


@njit(cache=True, _nrt=False, inline="always")
def _lattice_sums(y, rw, n):
    """The lattice form's charge terms of the source current: (conduction, motion)."""
    o = lat0(n)
    sj = 0.0
    si = 0.0
    for i in range(n):
        q = y[NODE0 + i]
        si += rw[o + LAT_IQ * n + i] * q
        sj += rw[o + LAT_JQ * n + i] * q
    return si, sj


@njit(cache=True, _nrt=False)
def _lattice_current(tab, par, y, xd, vdot, rw, scratch, n, NY):
    """The source current at y of the lattice form without R_s, its row rw (the maps at
    y's stroke) but for the current's weights, which this fills in; xd the stroke's rate
    (rhs with cur False leaves the current out: only the record reads it)."""
    xe = par[P_XE]
    i, f = _cell(tab, xe, min(max(y[X], 0.0), xe))
    _current_weights(tab, rw, i, f, n)
    si, sj = _lattice_sums(y, rw, n)
    V = y[NY - 2]
    return _source_current(par, rw, scratch, xd, V, V, vdot, sj, si, False, NY)


@njit(cache=True, _nrt=False, inline="always")
def _source_current(par, rw, ydot, xd, V, Vd, vdot, qmot, qcond, rs, NY):
    """The source current from the motion of the gap and the charges' conduction and
    charging (qmot, qcond: the charge states' terms of each); behind R_s the device
    voltage's own equation into ydot, else the capacitive current of the input's ramp.
    The inputs' rates are 0. Returns the current."""
    rest = xd * (rw[J0] * Vd + qmot) + rw[I0] * Vd + qcond
    if rs:
        I = (V - Vd) / par[P_RS]
        ydot[VD] = (I - rest) / rw[CAP]
    else:
        ydot[VD] = 0.0
        I = rw[CAP] * vdot + rest
    ydot[NY - 2] = 0.0
    ydot[NY - 1] = 0.0
    return I


@njit(cache=True, _nrt=False, inline="always")
def _core_rates(y, W, vdot, par, law, lawp, ydot, rw, pt, mode, qz, NY, side, cur=True):
    """The core's rates (stroke, velocity, V_d, layer) into ydot at the maps' row rw, the
    zipped points' mean charge qz. Returns (force, source current, and the couplings of
    the wakes to their source points: (ka, ra) the ahead wake's point and rate; (kb, rb,
    fb) the behind wake's, its source's derivative rb (1 - fb) in point kb's charge and
    rb fb in point kb + 1's)."""
    xe = par[P_XE]
    x = min(max(y[X], 0.0), xe)
    n = int(par[P_N])
    V = y[NY - 2]
    rs = par[P_RS] > 0.0
    Vd = y[VD] if rs else V
    # averaged mode: a segment's mean square voltage W (W < 0: a segment stepped as it is)
    avg = par[P_AVG] > 0.0 and W >= 0.0
    VV = W if avg else Vd * Vd
    qf, Pf = y[QF], y[PF]
    lat = par[P_LAT] > 0.0
    if lat:
        Fe = rw[C0] * VV + _charge_force(y, rw, n, Vd)
    else:
        Fe = rw[C0] * VV + rw[C1] * Vd * qf + rw[C2] * qf * qf
    if par[P_CHI] > 0.0 and n >= 2:
        Fe += _polarization_force(y, rw, n)
    net = Fe - y[NY - 1] - par[P_K] * x
    m = par[P_M]
    if m > 0.0:
        v = y[VEL]
        a = (net - par[P_B] * v) / m
        if mode == HELD or (mode == AUTO and ((y[X] <= 0.0 and v <= 0.0 and a < 0.0)
                                              or (y[X] >= xe and v >= 0.0 and a > 0.0))):
            v = 0.0
            a = 0.0
        xd = v
        ydot[VEL] = a
    else:
        xd = net / par[P_B]
        if mode == HELD or (mode == AUTO and ((y[X] <= 0.0 and xd < 0.0) or (y[X] >= xe and xd > 0.0))):
            xd = 0.0
        ydot[VEL] = 0.0
    ydot[X] = xd
    if lat:
        # the lattice form: every charge is a lattice point's (no layer, no wakes)
        for c in range(QF, SM + 1):
            ydot[c] = 0.0
        if not (cur or rs):
            # the current is not asked for and no state depends on it (cur: rhs)
            ydot[VD] = 0.0
            ydot[NY - 2] = 0.0
            ydot[NY - 1] = 0.0
            return Fe, math.nan, -1, 0.0, -1, 0.0, 0.0
        si, sj = _lattice_sums(y, rw, n)
        return Fe, _source_current(par, rw, ydot, xd, V, Vd, vdot, sj, si, rs, NY), -1, 0.0, -1, 0.0, 0.0
    # the front layer (an effective material point) and its wakes (zipped just behind:
    # the zipped gap; unzipped just ahead: the band's mean gap), each with its own rates
    _point(par, law, lawp, Vd, W, qf, Pf, rw[IUF], rw[T0F], pt)
    ydot[QF] = pt[0]
    ydot[PF] = pt[1]
    qb, Pb, qa, Pa = y[QB], y[PB], y[QA], y[PA]
    _point(par, law, lawp, Vd, W, qb, Pb, par[P_IU0], par[P_T0], pt)
    ydot[QB] = pt[0]
    ydot[PB] = pt[1]
    _point(par, law, lawp, Vd, W, qa, Pa, rw[IUA], par[P_T0], pt)
    ydot[QA] = pt[0]
    ydot[PA] = pt[1]
    # the renewal chain as the front moves at ld = dl_z/dt (module docstring): the layer
    # over ell = c_ell w_f, the wakes over c_w w_f; the side the front moves to blends
    # over the speed v_s (par P_VS, all but sharp: blending over creep speeds cost the
    # creep's physics, 40 % of the unzipping speed at v_s ~ the creep)
    ld = rw[DLZ] * xd
    ydot[SM] = 0.0
    ka, kb = -1, -1
    ra, rbs, fb = 0.0, 0.0, 0.0     # rbs: the behind wake's rate in its source points
    if n >= 2 and par[P_ICELL] > 0.0:
        if side != 0.0:
            # a side given (linear in the front's speed: an analysis of one branch)
            sp = side * ld
            A = sp if side > 0.0 else 0.0
            B = sp - A
        else:
            vs_ = par[P_VS]
            root = math.sqrt(ld * ld + vs_ * vs_)
            sp = root - vs_                              # |ld|, smooth at 0
            lds = sp * ld / root if root > 0.0 else 0.0  # ld, with the same smoothing
            e = 1.0
            if par[P_DM] > 0.0:
                # upwind renewal = central advection (reversible, linear in the speed) +
                # mixing (|speed|); within the material lag the mixing stops and the
                # advection keeps c_adv of itself (par P_ADV): a jitter moves the layer's
                # charge along the material and back. Frozen (c_adv 0), the layer lost the
                # exchange that makes a DC-amplitude PI loop oscillate in the full model.
                # The layer's material lags the front by s = y[SM] + l_z (a play operator:
                # y[SM] is its anchor, renewed after each accepted step, _replay); its gap
                # stays the moving frame's (modulating it within the lag changed neither the
                # holds nor the panel, docs/guide/surrogates.md)
                lag = par[P_DM] * rw[WF]
                sr = y[SM] + rw[LZ]
                e = min(1.0, max(0.0, (abs(sr) - lag) / (LAG_BAND * lag)))
                e = e * e * (3.0 - 2.0 * e)
            adv = par[P_ADV] + (1.0 - par[P_ADV]) * e
            A = 0.5 * (e * sp + adv * lds)                    # the advancing side's rate (m/s)
            B = 0.5 * (e * sp - adv * lds)                    # the retreating side's
        cf = par[P_ICELL] / rw[WF]
        cw = par[P_IWB] / rw[WF]
        ydot[QF] += cf * (A * (qa - qf) + B * (qb - qf))
        ydot[PF] += cf * (A * (Pa - Pf) + B * (Pb - Pf))
        ra, rb = cw * A, cw * B
        # each wake's source. Ahead: the first unzipped material point (the material the
        # front advances into keeps its own history there). Behind: the zipped material a
        # wake width back, interpolated between the points around it (the layer at the
        # front standing in for a point beyond it): the last zipped point, up to a point
        # spacing back, renewed a creeping front with material zipped long before it
        h = par[P_LE] / (n - 1)
        lz = rw[LZ]
        sb = max(lz - rw[WF] / par[P_IWB], 0.0) / h
        if not (lz == lz and sb == sb):   # a NaN stroke (_cell): NaN rates, the points' indices in range
            lz, sb = 0.0, 0.0
        ka = min(max(int(math.floor(lz / h + 1e-12)), 0) + 1, n - 1)
        qsa, Psa = y[NODE0 + ka], y[NODE0 + n + ka]
        kb = min(int(sb), n - 2)
        fb = sb - kb
        if (kb + 1) * h <= lz:
            qsb = (1.0 - fb) * y[NODE0 + kb] + fb * y[NODE0 + kb + 1]
            Psb = (1.0 - fb) * y[NODE0 + n + kb] + fb * y[NODE0 + n + kb + 1]
            rbs = rb
        else:
            g = (lz - sb * h) / (lz - kb * h) if lz > kb * h else 0.0    # point kb's weight
            qsb = (1.0 - g) * qf + g * y[NODE0 + kb]
            Psb = (1.0 - g) * Pf + g * y[NODE0 + n + kb]
            rbs, fb = rb * g, 0.0
        ydot[QA] += ra * (qsa - qa) + rb * (qf - qa)
        ydot[PA] += ra * (Psa - Pa) + rb * (Pb - Pa)     # P: from the zipped material (docstring)
        ydot[QB] += rb * (qsb - qb) + ra * (qf - qb)
        ydot[PB] += rb * (Psb - Pb) + ra * (Pf - Pb)
    # the source current: the layer's charge moves with the gap, the zipped points' conducts
    I = _source_current(par, rw, ydot, xd, V, Vd, vdot, rw[J1] * qf, rw[I1] * qz, rs, NY)
    return Fe, I, ka, ra, kb, rbs, fb


@njit(cache=True, _nrt=False)
def rhs(y, W, vdot, tab, par, law, lawp, ydot, rw, pt, mode, jn, side=0.0, cur=True):
    """dy/dt at y (the inputs' rows: 0, their slopes are set by the caller); W: the mean
    square drive in averaged mode, else ignored; vdot: the input voltage's slope (the
    capacitive current). mode FREE, HELD (the stroke rests on a stop) or AUTO (a stop
    holds it when the force pushes into it); jn: the points' 2 x 2 blocks are stored
    there if it has a row per point; cur False: the lattice form without R_s leaves the
    source current out (NaN; _lattice_current). Returns (electrostatic force, source
    current, ka, ra, kb, rb, fb: _core_rates)."""
    xe = par[P_XE]
    n = int(par[P_N])
    if par[P_LAT] > 0.0:
        lattice_row(tab, xe, min(max(y[X], 0.0), xe), rw, n, par[P_LE], par[P_CHI] > 0.0, cur or par[P_RS] > 0.0)
    else:
        table_row(tab, xe, min(max(y[X], 0.0), xe), rw)
    NY = NODE0 + 2 * n + 2
    qz = _points(y, W, par, law, lawp, ydot, rw, pt, jn, n, NY)
    return _core_rates(y, W, vdot, par, law, lawp, ydot, rw, pt, mode, qz, NY, side, cur)


@njit(cache=True, _nrt=False)
def on_stop(y, W, tab, par, law, lawp, ydot, rw, pt, jb0):
    """HELD if the stroke rests on a stop with the force pushing into it, else FREE (jb0:
    an empty (0, 4) array, rhs's "do not store the points' blocks")."""
    xe = par[P_XE]
    if 0.0 < y[X] < xe:
        return FREE
    rhs(y, W, 0.0, tab, par, law, lawp, ydot, rw, pt, FREE, jb0)
    if y[X] <= 0.0 and ydot[X] <= 0.0 and (par[P_M] == 0.0 or ydot[VEL] <= 0.0):
        return HELD
    if y[X] >= xe and ydot[X] >= 0.0 and (par[P_M] == 0.0 or ydot[VEL] >= 0.0):
        return HELD
    return FREE


@njit(cache=True, _nrt=False)
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


@njit(cache=True, _nrt=False)
def _lu_solve(M, piv, b, n):
    """Solve with _lu's factors: every row interchange first (_lu swaps whole rows, the
    multipliers of earlier columns included, so the interchanges must all be applied
    before the forward substitution, not one per column as it goes), then L and U."""
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for k in range(n):
        for i in range(k + 1, n):
            b[i] -= M[i, k] * b[k]
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= M[i, j] * b[j]
        b[i] = s / (M[i, i] if M[i, i] != 0.0 else 1e-300)


@njit(cache=True, _nrt=False, inline="always")
def _span(par, n):
    """The states below the inputs that can move: without the polarization branch the
    points' P block (NODE0 + n ..) stays 0 in every vector (the workspace's are zeroed),
    and the vector loops skip it (the same numbers: its entries were 0 + 0)."""
    return NODE0 + (2 * n if par[P_CHI] > 0.0 else n)


@njit(cache=True, _nrt=False, inline="always")
def _state(c, NY):
    """The state index of core slot c (0..NCORE-1): the core states, then the inputs."""
    return c if c < NODE0 else NY - NCORE + c


@njit(cache=True, _nrt=False, inline="always")
def _couple(g, Jb, Bi, k, rate, row, Mc, pos, m):
    """Eliminate point k's block from the wake's rows row, row + 1 (when they are core
    slots) that see it at `rate`: subtract (-g rate) Bi_k (-g Jb_k) from them."""
    if k < 0 or rate == 0.0:
        return
    for r in range(2):
        ri = pos[row + r]
        if ri < 0:
            continue
        for c in range(m):
            bq = -g * Jb[k, 0, c]
            bp = -g * Jb[k, 1, c]
            Mc[ri, c] -= -g * rate * (Bi[k, 2 * r] * bq + Bi[k, 2 * r + 1] * bp)


@njit(cache=True, _nrt=False)
def _factor(g, Jc, Jb, Jn, ka, ra, kb, rb, fb, n, Mc, piv, Bi, pos, m, cp, cq, rf, pol):
    """Factor I - g J: the points' 2 x 2 blocks (inverted into Bi), then the Schur
    complement of the m active core slots (the wakes' rows see their source points
    through the renewal; the mechanics' row rf sees every point's P through the
    polarization's force, at rates cp) into Mc, LU'd. pol: the actuator has the
    polarization branch (without it the blocks are diagonal)."""
    for i in range(n):
        a11 = 1.0 - g * Jn[i, 0]
        if not pol:
            # no polarization: each block is diag(a11, 1), its inverse diag(1 / a11, 1)
            # (the general formula's values exactly, with one division instead of four)
            d = a11 if a11 != 0.0 else 1e-300
            Bi[i, 0], Bi[i, 1], Bi[i, 2], Bi[i, 3] = 1.0 / d, 0.0, 0.0, 1.0 if a11 != 0.0 else 0.0
            continue
        a12 = -g * Jn[i, 1]
        a21 = -g * Jn[i, 2]
        a22 = 1.0 - g * Jn[i, 3]
        det = a11 * a22 - a12 * a21
        if det == 0.0:
            det = 1e-300
        Bi[i, 0], Bi[i, 1], Bi[i, 2], Bi[i, 3] = a22 / det, -a12 / det, -a21 / det, a11 / det
    for r in range(m):
        for c in range(m):
            Mc[r, c] = (1.0 if r == c else 0.0) - g * Jc[r, c]
    _couple(g, Jb, Bi, ka, ra, QA, Mc, pos, m)
    _couple(g, Jb, Bi, kb, rb * (1.0 - fb), QB, Mc, pos, m)
    _couple(g, Jb, Bi, kb + 1, rb * fb, QB, Mc, pos, m)
    if rf >= 0:
        # accumulated in a register, column by column (the same sums in the same order: a
        # running sum in Mc waited on its own store at every point)
        for c in range(m):
            acc = Mc[rf, c]
            for i in range(n):
                if cp[i] != 0.0:
                    acc -= g * g * cp[i] * (Bi[i, 2] * Jb[i, 0, c] + Bi[i, 3] * Jb[i, 1, c])
                if cq[i] != 0.0:
                    acc -= g * g * cq[i] * (Bi[i, 0] * Jb[i, 0, c] + Bi[i, 1] * Jb[i, 1, c])
            Mc[rf, c] = acc
    _lu(Mc, piv, m)


@njit(cache=True, _nrt=False, inline="always")
def _uncouple(g, Bi, k, rate, row, b, n, rc, pos):
    if k < 0 or rate == 0.0:
        return
    bq, bp = b[NODE0 + k], b[NODE0 + n + k]
    for r in range(2):
        ri = pos[row + r]
        if ri >= 0:
            rc[ri] -= -g * rate * (Bi[k, 2 * r] * bq + Bi[k, 2 * r + 1] * bp)


@njit(cache=True, _nrt=False)
def _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, b, NY, rc, cl, pos, m, cp, cq, rf, pol):
    """Solve (I - g J) z = b in place, with the factors of _factor (an inactive core
    state's row is the identity: its entry stays); pol: the actuator has the
    polarization branch."""
    for r in range(m):
        rc[r] = b[_state(cl[r], NY)]
    _uncouple(g, Bi, ka, ra, QA, b, n, rc, pos)                 # the points' right-hand
    _uncouple(g, Bi, kb, rb * (1.0 - fb), QB, b, n, rc, pos)    # sides, eliminated from
    _uncouple(g, Bi, kb + 1, rb * fb, QB, b, n, rc, pos)        # the wakes' rows
    if rf >= 0:                                       # and from the mechanics' row
        acc = rc[rf]                                  # (in a register: _factor)
        for i in range(n):
            if cp[i] != 0.0:
                acc += g * cp[i] * (Bi[i, 2] * b[NODE0 + i] + Bi[i, 3] * b[NODE0 + n + i])
            if cq[i] != 0.0:
                acc += g * cq[i] * (Bi[i, 0] * b[NODE0 + i] + Bi[i, 1] * b[NODE0 + n + i])
        rc[rf] = acc
    _lu_solve(Mc, piv, rc, m)
    for r in range(m):
        b[_state(cl[r], NY)] = rc[r]
    if not pol:
        # no polarization branch: the points' P rows and couplings are zero (their
        # entries of b stay 0), so each point's charge is a scalar equation
        if m == 1:
            # one active core state (the stroke, inputs constant): the loop below unrolled
            r0, ng = rc[0], -g
            for i in range(n):
                b[NODE0 + i] = Bi[i, 0] * (b[NODE0 + i] - ng * Jb[i, 0, 0] * r0)
            return
        for i in range(n):
            bq = b[NODE0 + i]
            for c in range(m):
                bq -= -g * Jb[i, 0, c] * rc[c]
            b[NODE0 + i] = Bi[i, 0] * bq
        return
    for i in range(n):
        bq, bp = b[NODE0 + i], b[NODE0 + n + i]
        for c in range(m):
            bq -= -g * Jb[i, 0, c] * rc[c]
            bp -= -g * Jb[i, 1, c] * rc[c]
        b[NODE0 + i] = Bi[i, 0] * bq + Bi[i, 1] * bp
        b[NODE0 + n + i] = Bi[i, 2] * bq + Bi[i, 3] * bp


@njit(cache=True, _nrt=False)
def _jacobian(y, W, vd, tab, par, law, lawp, ft, rw, rw0, pt, mode, side, sc, xe, n, NY, m, cl, Jc, Jb, k1, yt, Jb0):
    """The Jacobian's core columns at y (ft = f(y), rw0 its maps' row): forward
    differences in the m active core slots cl, into Jc (core rows) and Jb (the points'
    rows). Only the stroke's column moves the maps and only the stroke's, the input
    voltage's and V_d's move the points: the others difference the core alone, at the
    same maps' row."""
    qz0 = _zipped_mean(y, rw0, par, n)
    for ci in range(m):
        c = cl[ci]
        j = _state(c, NY)
        # the step follows the state's sign: the difference is then mirrored
        # under V -> -V (odd physics, the same steps for either polarity)
        dj = 1e-7 * max(abs(y[j]), sc[j])
        if y[j] < 0.0:
            dj = -dj
        if j == X and y[X] >= xe:
            dj = -dj
        for i in range(_span(par, n)):
            yt[i] = y[i]
        yt[NY - 2], yt[NY - 1] = y[NY - 2], y[NY - 1]
        yt[j] += dj
        moves = j == X or j == NY - 2 or j == VD
        if j == X:
            rhs(yt, W, vd, tab, par, law, lawp, k1, rw, pt, mode, Jb0, side, False)
        elif moves:
            qzj = _points(yt, W, par, law, lawp, k1, rw0, pt, Jb0, n, NY)
            _core_rates(yt, W, vd, par, law, lawp, k1, rw0, pt, mode, qzj, NY, side, False)
        else:
            _core_rates(yt, W, vd, par, law, lawp, k1, rw0, pt, mode, qz0, NY, side, False)
        for ri in range(m):
            r = _state(cl[ri], NY)
            Jc[ri, ci] = (k1[r] - ft[r]) / dj if r < NY - 2 else 0.0
        for i in range(n):
            if moves:
                Jb[i, 0, ci] = (k1[NODE0 + i] - ft[NODE0 + i]) / dj
                Jb[i, 1, ci] = (k1[NODE0 + n + i] - ft[NODE0 + n + i]) / dj
            else:
                Jb[i, 0, ci] = 0.0
                Jb[i, 1, ci] = 0.0


@njit(cache=True, _nrt=False)
def _mirror(Jc, Jb, cl, m, n, pol):
    """The Jacobian at the mirrored state (V -> -V): M J M, M negating every state but
    the stroke and its velocity (and the force input). Without the polarization branch
    (pol False) the points' P rows are zero and stay as they are."""
    for ci in range(m):
        sc_ = 1.0 if (cl[ci] == X or cl[ci] == VEL or cl[ci] == NCORE - 1) else -1.0
        for ri in range(m):
            sr = 1.0 if (cl[ri] == X or cl[ri] == VEL or cl[ri] == NCORE - 1) else -1.0
            Jc[ri, ci] *= sr * sc_
        for i in range(n):
            Jb[i, 0, ci] *= -sc_
            if pol:
                Jb[i, 1, ci] *= -sc_


@njit(cache=True, inline="always")
def _active_states(par, n, NY):
    """The states this actuator has (the others stay 0: no error, no Jacobian column)."""
    active = np.zeros(NY, dtype=np.bool_)
    active[X] = True
    active[VEL] = par[P_M] > 0.0
    active[VD] = par[P_RS] > 0.0
    lat = par[P_LAT] > 0.0
    active[QF] = not lat
    active[PF] = par[P_CHI] > 0.0 and not lat
    chain = n >= 2 and par[P_ICELL] > 0.0
    active[QB] = chain
    active[QA] = chain
    active[PB] = chain and par[P_CHI] > 0.0
    active[PA] = chain and par[P_CHI] > 0.0
    active[SM] = False       # a memory (rate 0, fixed within a step): no Jacobian column
    for i in range(n):
        active[NODE0 + i] = True
        active[NODE0 + n + i] = par[P_CHI] > 0.0
    return active


@njit(cache=True, _nrt=False)
def _columns(active, vs_k, fs_k, pos, cl):
    """The active core slots of a segment (the inputs' slots while they ramp): cl lists
    them, pos maps a slot to its place among them (-1: inactive). Returns their number."""
    m = 0
    for c in range(NCORE):
        on = active[c] if c < NODE0 else (vs_k != 0.0 if c == NCORE - 2 else fs_k != 0.0)
        pos[c] = m if on else -1
        if on:
            cl[m] = c
            m += 1
    return m


@njit(cache=True, _nrt=False)
def _kept_jacobian(y, yJ, js, clJ, cl, m, active, sc, NY, mode, ramps):
    """Jacobian reuse across a polarity inversion: odd physics gives J(My, -V) = M J(y, V) M
    (M negating the charges), and a half period later the state is near the mirror of
    the one the Jacobian was taken at. Kept (mirrored) while within JAC_TOL of it, at
    most JAC_USES times; the pair is a W-method (order 2 with any Jacobian); retaken
    after a rejection. Within a stage it is always retaken: there a kept Jacobian let
    the steps grow past what the order-3 error estimate, which assumes the exact one,
    can see (5-7 % of range lost on a DC staircase and a 0.3 Hz inversion at JAC_TOL =
    0.02). js = [fresh, uses, m, V, near] of the kept one.

    near (the compiled hold, pi_loop: a sample is one step of at most its period, so the
    steps cannot grow past the estimate): also kept at a voltage within JAC_TOL of the
    one it was taken at, or of its mirror, the state within JAC_TOL as above. Returns 0:
    retake it; 1: mirror it; 2: keep it as it is."""
    if js[J_FRESH] != 0.0 or mode != FREE or ramps or m != js[J_M] or js[J_USES] >= JAC_USES:
        return 0
    V, VJ = y[NY - 2], js[J_V]
    if V == -VJ and V != 0.0:
        how = 1
    elif js[J_NEAR] != 0.0 and V != 0.0 and abs(V - VJ) <= JAC_TOL * abs(VJ):
        how = 2
    elif js[J_NEAR] != 0.0 and V != 0.0 and abs(V + VJ) <= JAC_TOL * abs(VJ):
        how = 1
    else:
        return 0
    for ci in range(m):
        if cl[ci] != clJ[ci]:
            return 0
    dev = 0.0
    for i in range(NY - 2):
        if active[i]:
            ref = yJ[i] if (i == X or i == VEL or how == 2) else -yJ[i]
            dev = max(dev, abs(y[i] - ref) / (abs(y[i]) + sc[i]))
    return how if dev <= JAC_TOL else 0


@njit(cache=True, _nrt=False)
def _hold_jacobian(Jc, Jb, pos, m, n):
    """On a stop (HELD): the stroke's and velocity's rows and columns decouple."""
    for ci in range(m):
        for c in (X, VEL):
            if pos[c] >= 0:
                Jc[pos[c], ci] = 0.0
                Jc[ci, pos[c]] = 0.0
    for i in range(n):
        Jb[i, 0, pos[X]] = 0.0
        Jb[i, 1, pos[X]] = 0.0


@njit(cache=True, _nrt=False)
def _stages(y, hs, W, vd, tab, par, law, lawp, rw, pt, mode, side, F0, F1, F2, k1, k2, k3, yt, g, Jb, ka, ra, kb, rb,
            fb, Jb0, n, Mc, piv, Bi, NY, rc, cl, pos, m, cp, cq, rf, Jn2, vs_k, fs_k, active, rtol, sc):
    """One Rosenbrock-W step of size hs from y (F0 = f(y); the matrix I - g J factored):
    the three stages of ode23s and the scaled error of the embedded pair. yt receives the
    new state, F2 f there. Returns (error, and rhs's results at yt: force, current (NaN in
    the lattice form without R_s: _lattice_current) and the wakes' couplings)."""
    d_e32 = 6.0 + math.sqrt(2.0)
    pol = par[P_CHI] > 0.0
    # the vectors over the states that move (_span) and the two inputs, each in two plain
    # loops (one loop over both spans, through a tuple of ranges, was 16 % slower a step)
    hi = _span(par, n)
    for i in range(hi):
        k1[i] = F0[i]
    k1[NY - 2], k1[NY - 1] = F0[NY - 2], F0[NY - 1]
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k1, NY, rc, cl, pos, m, cp, cq, rf, pol)
    for i in range(hi):
        yt[i] = y[i] + 0.5 * hs * k1[i]
    for i in range(NY - 2, NY):
        yt[i] = y[i] + 0.5 * hs * k1[i]
    rhs(yt, W, vd, tab, par, law, lawp, F1, rw, pt, mode, Jb0, side, False)
    F1[NY - 2] = vs_k
    F1[NY - 1] = fs_k
    for i in range(hi):
        k2[i] = F1[i] - k1[i]
    for i in range(NY - 2, NY):
        k2[i] = F1[i] - k1[i]
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k2, NY, rc, cl, pos, m, cp, cq, rf, pol)
    for i in range(hi):
        k2[i] += k1[i]
        yt[i] = y[i] + hs * k2[i]
    for i in range(NY - 2, NY):
        k2[i] += k1[i]
        yt[i] = y[i] + hs * k2[i]
    Fe2, I2, ka2, ra2, kb2, rb2, fb2 = rhs(yt, W, vd, tab, par, law, lawp, F2, rw, pt, mode, Jn2, side, False)
    F2[NY - 2] = vs_k
    F2[NY - 1] = fs_k
    for i in range(hi):
        k3[i] = F2[i] - d_e32 * (k2[i] - F1[i]) - 2.0 * (k1[i] - F0[i])
    for i in range(NY - 2, NY):
        k3[i] = F2[i] - d_e32 * (k2[i] - F1[i]) - 2.0 * (k1[i] - F0[i])
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k3, NY, rc, cl, pos, m, cp, cq, rf, pol)
    err = 0.0
    for i in range(hi):
        if active[i]:
            e = hs / 6.0 * (k1[i] - 2.0 * k2[i] + k3[i]) / (rtol * (abs(y[i]) + sc[i]))
            err = worst(err, abs(e))
    return err, Fe2, I2, ka2, ra2, kb2, rb2, fb2


@njit(cache=True, _nrt=False, inline="always")
def _ros_stage(y, hs, a1, a2, a3, c1, c2, c3, k1, k2, k3, kn, W, vd, tab, par, law, lawp, F1, rw, pt, mode, side, Jb0,
               vs_k, fs_k, hi, NY):
    """One ROS34PW2 stage's right-hand side into kn: gam (f(y + hs (a1 k1 + a2 k2 + a3 k3))
    + c1 k1 + c2 k2 + c3 k3) (F1 and the stage state, in kn first, are scratch)."""
    for i in range(hi):
        kn[i] = y[i] + hs * (a1 * k1[i] + a2 * k2[i] + a3 * k3[i])
    for i in range(NY - 2, NY):
        kn[i] = y[i] + hs * (a1 * k1[i] + a2 * k2[i] + a3 * k3[i])
    rhs(kn, W, vd, tab, par, law, lawp, F1, rw, pt, mode, Jb0, side, False)
    F1[NY - 2] = vs_k
    F1[NY - 1] = fs_k
    for i in range(hi):
        kn[i] = R_GAM * (F1[i] + c1 * k1[i] + c2 * k2[i] + c3 * k3[i])
    for i in range(NY - 2, NY):
        kn[i] = R_GAM * (F1[i] + c1 * k1[i] + c2 * k2[i] + c3 * k3[i])


@njit(cache=True, _nrt=False)
def _stages_ros34(y, hs, W, vd, tab, par, law, lawp, rw, pt, mode, side, F0, F1, F2, k1, k2, k3, k4, yt, g, Jb, ka,
                  ra, kb, rb, fb, Jb0, n, Mc, piv, Bi, NY, rc, cl, pos, m, cp, cq, rf, Jn2, vs_k, fs_k, active, rtol,
                  sc):
    """_stages with ROS34PW2 (the matrix I - g J factored, g = R_GAM hs): four stages, the
    new state in yt, f there in F2, the scaled error of the embedded pair. In a slow creep
    ode23s's error estimate was of order 1-2 on the massless stroke (flat at 0.1-0.4 over
    steps of 0.02-0.2 s; on a singularly perturbed test problem its fast component's
    estimate falls as h^2, ROS34PW2's as h^3 and 10x smaller) and set the creep's steps,
    a third of them rejected where the front crosses a material point. The records are
    no closer to the stroke's balance with it (about 1.5 mN of force off, median): the
    gain is in the estimate."""
    pol = par[P_CHI] > 0.0
    hi = _span(par, n)
    for i in range(hi):
        k1[i] = R_GAM * F0[i]
    k1[NY - 2], k1[NY - 1] = R_GAM * F0[NY - 2], R_GAM * F0[NY - 1]
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k1, NY, rc, cl, pos, m, cp, cq, rf, pol)
    _ros_stage(y, hs, R_A21, 0.0, 0.0, R_C21, 0.0, 0.0, k1, k1, k1, k2, W, vd, tab, par, law, lawp, F1, rw, pt, mode,
               side, Jb0, vs_k, fs_k, hi, NY)
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k2, NY, rc, cl, pos, m, cp, cq, rf, pol)
    _ros_stage(y, hs, R_A31, R_A32, 0.0, R_C31, R_C32, 0.0, k1, k2, k2, k3, W, vd, tab, par, law, lawp, F1, rw, pt,
               mode, side, Jb0, vs_k, fs_k, hi, NY)
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k3, NY, rc, cl, pos, m, cp, cq, rf, pol)
    _ros_stage(y, hs, R_A41, R_A42, R_A43, R_C41, R_C42, R_C43, k1, k2, k3, k4, W, vd, tab, par, law, lawp, F1, rw, pt,
               mode, side, Jb0, vs_k, fs_k, hi, NY)
    _solve(g, Jb, ka, ra, kb, rb, fb, n, Mc, piv, Bi, k4, NY, rc, cl, pos, m, cp, cq, rf, pol)
    for i in range(hi):
        yt[i] = y[i] + hs * (R_M1 * k1[i] + R_M2 * k2[i] + R_M3 * k3[i] + R_M4 * k4[i])
    for i in range(NY - 2, NY):
        yt[i] = y[i] + hs * (R_M1 * k1[i] + R_M2 * k2[i] + R_M3 * k3[i] + R_M4 * k4[i])
    Fe2, I2, ka2, ra2, kb2, rb2, fb2 = rhs(yt, W, vd, tab, par, law, lawp, F2, rw, pt, mode, Jn2, side, False)
    F2[NY - 2] = vs_k
    F2[NY - 1] = fs_k
    err = 0.0
    for i in range(hi):
        if active[i]:
            e = hs * (R_E1 * k1[i] + R_E2 * k2[i] + R_E3 * k3[i] + R_E4 * k4[i]) / (rtol * (abs(y[i]) + sc[i]))
            err = worst(err, abs(e))
    return err, Fe2, I2, ka2, ra2, kb2, rb2, fb2


@njit(cache=True, inline="always")
def _to_stop(y0, y1, xe, hs, tries):
    """A step from stroke y0 that ends at y1 past a stop is shortened to end on it (an
    event; at most 6 tries, then within 1e-9 x_e past it counts as on it, and a shortened
    one within LAND_SHARE of its travel). Returns the shortened step, or 0 to accept this
    one."""
    f_near, f_far, side = to_stop(y0, y1, xe)
    over = f_near / (f_near - f_far) if side != 0 else 0.0
    # on it: within 1e-9 x_e past it, or, once shortened, within LAND_SHARE of the travel (_snap)
    near = max(1e-9 * xe, LAND_SHARE * abs(y1 - y0)) if tries > 0 else 1e-9 * xe
    if over == 0.0 or tries >= 6 or (y1 < 0.0 and y1 > -near) or (y1 > xe and y1 < xe + near):
        return 0.0
    return hs * (min(max(over, 1e-3), 0.999) * 1.0001 if tries < 3 else 1.0001 * over)


@njit(cache=True, _nrt=False, inline="always")
def _dx_bound(xe, tab, lat):
    """The most an accepted step moves the stroke: DX_STEP x_e, and in the lattice form at
    most LAT_CELLS of the tables' grid intervals."""
    return min(DX_STEP * xe, LAT_CELLS * xe / (tab.shape[0] - 1)) if lat else DX_STEP * xe


@njit(cache=True, _nrt=False, inline="always")
def _off_bound(hs, off):
    """The next step's most after a step of hs that ended `off` tolerances off the
    stroke's balance (RELAX's test; OFF_ORDER): the error estimate does not see it."""
    return hs * OFF_SAFETY * max(off, 1e-12) ** (-1.0 / OFF_ORDER)


@njit(cache=True, _nrt=False, inline="always")
def _snap(x0, yt, xe):
    """A step shortened onto a stop (_to_stop) that ends short of it by a hair (within
    LAND_SHARE of its travel) ends on it: left a few nanometres inside, the next step was
    a free one into the stop, shortened twice more (3 tries of a unipolar train's 33 a
    period). Returns whether it moved yt."""
    near = LAND_SHARE * abs(yt[X] - x0)
    if 0.0 < yt[X] <= near:
        yt[X] = 0.0
    elif xe - near <= yt[X] < xe:
        yt[X] = xe
    else:
        return False
    if (yt[X] == 0.0 and yt[VEL] < 0.0) or (yt[X] == xe and yt[VEL] > 0.0):
        yt[VEL] = 0.0
    return True


@njit(cache=True, _nrt=False)
def _clip(y, xe):
    """The accepted state on the stops: the stroke within [0, x_e], a velocity into a stop
    zeroed. Returns whether it was clipped."""
    if y[X] < 0.0:
        y[X] = 0.0
        if y[VEL] < 0.0:
            y[VEL] = 0.0
        return True
    if y[X] > xe:
        y[X] = xe
        if y[VEL] > 0.0:
            y[VEL] = 0.0
        return True
    return False


@njit(cache=True, _nrt=False)
def _replay(y, tab, par, xe):
    """The play operator's anchor after an accepted step: the lag clipped at the new
    stroke (to the band's outer edge, where the renewal is whole and flat: a step that
    starts there meets no kink), less its zipped length."""
    lz = table_value(tab, xe, y[X], LZ)
    lim = (1.0 + LAG_BAND) * par[P_DM] * table_value(tab, xe, y[X], WF)
    s = min(lim, max(-lim, y[SM] + lz))
    y[SM] = s - lz


@njit(cache=True, _nrt=False)
def _land(y, yt, xe, last, V_end, F_end, NY, hi):
    """The accepted state yt into y, clipped to the stops (_clip); a step that ends the
    segment lands exactly on the breakpoint's inputs. Returns whether it was clipped.
    hi: the states that move (_span; the P block beyond stays as it is)."""
    for i in range(hi):
        y[i] = yt[i]
    y[NY - 2], y[NY - 1] = yt[NY - 2], yt[NY - 1]
    clipped = _clip(y, xe)
    if last:
        y[NY - 2] = V_end
        y[NY - 1] = F_end
    return clipped


@njit(cache=True, _nrt=False)
def _finite(y, NY):
    """No NaN in y. An or over every entry, not a return at the first NaN: that loop
    vectorizes (21 ns against 70 for the 174 states of the standard protocol's lattice,
    once an accepted step)."""
    bad = 0
    for i in range(NY):
        bad |= y[i] != y[i]
    return bad == 0


@njit(cache=True, _nrt=False)
def _step_jacobian(y, W, vd, tab, par, law, lawp, ft, rw, rw0, pt, mode, side, sc, xe, n, NY, m, cl, Jc, Jb, k1, yt,
                   Jb0, yJ, js, clJ, pos, active, f_ramps):
    """The Jacobian of a step: the kept one mirrored (_kept_jacobian) or a new one
    (_jacobian), edited on a stop (_hold_jacobian). Returns whether it was kept."""
    how = _kept_jacobian(y, yJ, js, clJ, cl, m, active, sc, NY, mode, vd != 0.0 or f_ramps)
    reuse = how != 0
    js[J_FRESH] = 0.0
    if reuse:
        js[J_USES] += 1.0
        if how == 1:
            _mirror(Jc, Jb, cl, m, n, par[P_CHI] > 0.0)
            for i in range(_span(par, n)):
                if not (i == X or i == VEL):
                    yJ[i] = -yJ[i]
            js[J_V] = -js[J_V]
    else:
        js[J_USES], js[J_M], js[J_V] = 0.0, m, y[NY - 2]
        for ci in range(m):
            clJ[ci] = cl[ci]
        for i in range(_span(par, n)):
            yJ[i] = y[i]
        _jacobian(y, W, vd, tab, par, law, lawp, ft, rw, rw0, pt, mode, side, sc, xe, n, NY, m, cl, Jc, Jb, k1, yt,
                  Jb0)
    if mode == HELD:
        js[J_FRESH] = 1.0    # the held Jacobian is edited: not for a free step
        _hold_jacobian(Jc, Jb, pos, m, n)
    return reuse


@njit(cache=True, _nrt=False)
def _carry(ft, F2, Jn, Jn2, rw0, rw, par, n, hi):
    """First same as last: the accepted step's last stage (f, the points' blocks, the
    maps' row) is the next step's start. Copied: swapping the arrays instead slowed every
    step by a third (numba's code for arrays reassigned in the loop)."""
    for i in range(hi):
        ft[i] = F2[i]
    for i in range(n):
        for c in range(4):
            Jn[i, c] = Jn2[i, c]
    _copy_row(rw0, rw, par, n)


@njit(cache=True, _nrt=False, inline="always")
def _copy_row(rw0, rw, par, n):
    """rw0 = rw where a step's start reads it. The lattice form's P weights are read only
    with the polarization branch, its current weights only behind R_s (else the record
    fills them in, _lattice_current): on Table 1 a third of the row."""
    if par[P_LAT] == 0.0:
        for c in range(rw.shape[0]):
            rw0[c] = rw[c]
        return
    o = lat0(n)
    top = NFIX + (3 * n if par[P_CHI] > 0.0 else n)
    for k in range(top):
        c = np.uint64(k)
        rw0[c] = rw[c]
    end = o + (LAT_JQ + 1) * n if par[P_RS] > 0.0 else o + LAT_IQ * n
    for k in range(end - o):
        c = np.uint64(o + k)
        rw0[c] = rw[c]
    rw0[rw.shape[0] - 1] = rw[rw.shape[0] - 1]


@njit(cache=True)
def _workspace(tab, par):
    """integrate's arrays, allocated once (pi_loop keeps them across its samples)."""
    n = int(par[P_N])
    NY = NODE0 + 2 * n + 2
    nb = max(n, 1)
    # zeroed: without the branch the points' P entries are never written (_span)
    return (np.zeros(NY), np.zeros(NY), np.zeros(NY), np.zeros(NY), np.zeros(NY), np.zeros(NY), np.zeros(NY),
            np.zeros(NY),                                          # F0, F1, F2, k1, k2, k3, yt, ft
            np.empty(tab.shape[1] + 1), np.empty(tab.shape[1] + 1),  # rw, rw0 (+ 1: lattice_row's k0)
            np.empty(6), np.empty((0, 4)),       # pt; Jb0: "do not store the points' blocks"
            np.zeros((NCORE, NCORE)),            # Jc: the active core slots' rows x columns (compressed)
            np.zeros((nb, 2, NCORE)),            # Jb: the points' rows x the active core columns
            np.zeros((nb, 4)), np.zeros((nb, 4)),  # Jn, Jn2: the points' own 2 x 2 blocks at the step's start, end
            np.empty((NCORE, NCORE)), np.empty((nb, 4)),  # Mc, Bi
            np.empty(NCORE, dtype=np.int64), np.empty(NCORE),  # piv, rc
            np.empty(NCORE, dtype=np.int64),     # cl: the active core slots
            np.empty(NCORE, dtype=np.int64),     # pos: slot -> its place among them (-1: inactive)
            np.zeros(nb), np.zeros(nb),          # cp, cq: the mechanics' row's answer to each point's P, charge
            _active_states(par, n, NY), np.zeros(NY), np.empty(NCORE, dtype=np.int64),   # active, yJ, clJ
            np.zeros(5),                         # js: the kept Jacobian (J_NEAR 0: integrate's own)
            np.zeros(NY))                        # k4: ROS34PW2's fourth stage


@njit(cache=True)
def integrate(tb, v0, vs, f0, fs, w2, gof, y0, tab, par, law, lawp, sc, rtol, h0, rec, max_steps):
    """_integrate from a copy of y0, with a workspace of its own (its docstring). Returns
    (status, rows, steps, y)."""
    y = y0.copy()
    status, rows, steps = _integrate(tb, v0, vs, f0, fs, w2, gof, y, tab, par, law, lawp, sc, rtol, h0, rec,
                                     max_steps, _workspace(tab, par))
    return status, rows, steps, y


# no reference counting (_nrt=False): it allocates nothing and y is the caller's. Counted, the
# workspace's 28 arrays were taken and released at each call, a tenth of a compiled hold's
# time (pi_loop calls it once a sample)
@njit(cache=True, _nrt=False)
def _integrate(tb, v0, vs, f0, fs, w2, gof, y, tab, par, law, lawp, sc, rtol, h0, rec, max_steps, ws):
    """Integrate over the input segments [tb[k], tb[k+1]] (voltage v0[k] + vs[k] (t - tb[k]),
    force likewise; in averaged mode (par[P_AVG]) w2[k] >= 0 is the segment's mean square
    voltage, the period mean <V> its voltage, and w2[k] < 0 a segment stepped as it is).
    gof[k] = (g, W): at segment k's start the charges move by b g (b their input gains at
    the mean square voltage W, _phase_offset): a cycle-averaged window's period-mean charge
    against the real waveform's at its phase (reduced.fast_inversions). Writes one record
    row per accepted step (and the start) into rec; y (the start) is advanced in place.
    Returns (status, rows, steps).

    Per step: the Jacobian kept across an inversion (_kept_jacobian) or renewed
    (_jacobian), edited on a stop (_hold_jacobian), factored (_factor); the three stages
    and the error (_stages); a step past a stop shortened onto it (_to_stop); the state
    clipped to the stops (_clip) and recorded."""
    n = int(par[P_N])
    NY = NODE0 + 2 * n + 2
    hi = _span(par, n)
    (F0, F1, F2, k1, k2, k3, yt, ft, rw, rw0, pt, Jb0, Jc, Jb, Jn, Jn2, Mc, Bi, piv, rc, cl, pos, cp, cq, active, yJ,
     clJ, js, k4) = ws
    pol_force = par[P_CHI] > 0.0 and n >= 2
    lat = par[P_LAT] > 0.0
    nrec = rec.shape[0]
    xe = par[P_XE]
    d = 1.0 / (2.0 + math.sqrt(2.0))
    if js[J_NEAR] == 0.0:
        js[J_FRESH], js[J_USES], js[J_M], js[J_V] = 1.0, 0.0, -1.0, 0.0   # the kept Jacobian: none
    steps = 0
    h_land = 0.0        # a step before it was shortened onto a stop
    mode = np.int64(FREE)   # typed as on_stop returns it (a literal 0 failed to unify in some builds)
    side = 0.0          # the renewal takes the side the front moves to (rhs's side argument: 0)
    h = h0
    y[NY - 2] = v0[0]
    y[NY - 1] = f0[0]
    Fe, I, ka, ra, kb, rb, fb = rhs(y, w2[0], vs[0], tab, par, law, lawp, ft, rw0, pt, AUTO, Jn)
    _record(rec, 0, tb[0], y, I, Fe, NY)
    row = 1
    # inside the stops (AUTO is FREE there) the start's rates, blocks and row serve the first step
    have0 = 0.0 < y[X] < xe and gof[0, 0] == 0.0
    for seg in range(len(v0)):
        t, t_end = tb[seg], tb[seg + 1]
        y[NY - 2], y[NY - 1] = v0[seg], f0[seg]
        W, vd = w2[seg], vs[seg]
        if gof[seg, 0] != 0.0:
            _phase_offset(y, gof[seg, 0], gof[seg, 1], tab, par, law, lawp, k1, k2, yt, rw, pt, NY, Jb0)
        m = _columns(active, vs[seg], fs[seg], pos, cl)
        F0[NY - 2], F0[NY - 1] = vs[seg], fs[seg]
        have = have0 and seg == 0   # ft, Jn, rw0 and the couplings hold f at y (free): the last stage's
        while t < t_end - 1e-13 * max(abs(t_end), 1.0):
            if steps >= max_steps:
                return MAX_STEPS, row, steps
            hs = h
            last = False
            if t + 1.1 * hs >= t_end:
                hs = t_end - t
                last = True
            mode = on_stop(y, W, tab, par, law, lawp, ft, rw, pt, Jb0)
            if not (have and mode == FREE):
                Fe, I, ka, ra, kb, rb, fb = rhs(y, W, vd, tab, par, law, lawp, ft, rw, pt, mode, Jn, side, False)
                _copy_row(rw0, rw, par, n)
            for i in range(hi):
                F0[i] = ft[i]
            reuse = _step_jacobian(y, W, vd, tab, par, law, lawp, ft, rw, rw0, pt, mode, side, sc, xe, n, NY, m, cl,
                                   Jc, Jb, k1, yt, Jb0, yJ, js, clJ, pos, active, fs[seg] != 0.0)
            if mode == HELD:
                F0[X] = 0.0
                F0[VEL] = 0.0
            elif F0[X] != 0.0:
                # the first try moves the stroke, at its start's rate, by at most DX_FIRST of
                # a step's most (_dx_bound); without a mass, not when it heads for a balance
                # nearer than that (a polarity inversion's dip)
                dx_first = DX_FIRST * _dx_bound(xe, tab, lat)
                jxx = Jc[pos[X], pos[X]]
                far = par[P_M] > 0.0 or jxx >= 0.0 or abs(F0[X]) > -jxx * dx_first
                if far and abs(F0[X]) * hs > dx_first:
                    hs = dx_first / abs(F0[X])
                    last = False
            # the polarization's force couples the mechanics' row to every point's P
            rf = -1
            if (pol_force or lat) and mode == FREE:
                rf = pos[VEL] if par[P_M] > 0.0 else pos[X]
                rate = 1.0 / (par[P_M] if par[P_M] > 0.0 else par[P_B])
                if pol_force:
                    _polarization_slopes(y, rw0, n, rate, cp)
                if lat:
                    _charge_slopes(y, rw0, n, y[VD] if par[P_RS] > 0.0 else y[NY - 2], rate, cq)
            tries = 0
            snapped = False
            redo = False
            while True:
                steps += 1
                # the lattice's long steps without a mass: ROS34PW2 (the ROS_SWITCH note)
                ros = lat and par[P_M] == 0.0 and mode == FREE and -Jc[pos[X], pos[X]] * hs >= ROS_SWITCH
                g = (R_GAM if ros else d) * hs
                _factor(g, Jc, Jb, Jn, ka, ra, kb, rb, fb, n, Mc, piv, Bi, pos, m, cp, cq, rf, par[P_CHI] > 0.0)
                if ros:
                    err, Fe2, I2, ka2, ra2, kb2, rb2, fb2 = _stages_ros34(
                        y, hs, W, vd, tab, par, law, lawp, rw, pt, mode, side, F0, F1, F2, k1, k2, k3, k4, yt, g, Jb,
                        ka, ra, kb, rb, fb, Jb0, n, Mc, piv, Bi, NY, rc, cl, pos, m, cp, cq, rf, Jn2, vs[seg], fs[seg],
                        active, rtol, sc)
                else:
                    err, Fe2, I2, ka2, ra2, kb2, rb2, fb2 = _stages(
                        y, hs, W, vd, tab, par, law, lawp, rw, pt, mode, side, F0, F1, F2, k1, k2, k3, yt, g, Jb,
                        ka, ra, kb, rb, fb, Jb0, n, Mc, piv, Bi, NY, rc, cl, pos, m, cp, cq, rf, Jn2, vs[seg], fs[seg],
                        active, rtol, sc)
                if not (err == err):
                    return NONFINITE, row, steps
                # a step moves the stroke by at most DX_STEP x_e, on the error's scale (cubed,
                # as the controller's exponent): across a snap the order-3 estimate passed a
                # step that overshot (Table 1, 5 -> 6 kV after charging, rtol 3e-4: one step
                # of 14 ms from 309 to 1495 um, the full model peaking at 1106). The lattice: at
                # most LAT_CELLS grid intervals too (a 10 Hz train's snap off the stop, 0 to
                # 633 um in one 1.2 ms step of 2.6 time constants, was estimated at 0.9 and
                # 80 um off)
                dx_max = _dx_bound(xe, tab, lat)   # here, not before the loops: hoisted, the AOT hold ran 6 % slower
                err = max(err, (abs(yt[X] - y[X]) / dx_max) ** 3)
                # without a mass the stroke flows to the balance of the frozen charges (at a
                # distance of the rate over the stroke's own rate constant, -J_xx): a step that
                # ends further from it than the tolerance and either passed it (ends moving
                # back) or lasted RELAX time constants (where any start has relaxed) is wrong.
                # An L-stable pair's error estimate fades as a step outgrows the mechanics'
                # time constant: a snap onto a spring, one 7 ms step from 0 to 805 um with the
                # balance at 532, was estimated at half the tolerance; a 0.1 s telegraph hold
                # taken in one step ended 85 um under it
                jxx = Jc[pos[X], pos[X]]
                h_off = np.inf     # the next step's bound from the end's distance to the balance
                if par[P_M] == 0.0 and mode == FREE and jxx < 0.0:
                    off = abs(F2[X]) / (-jxx * rtol * (abs(yt[X]) + sc[X]))   # in tolerances
                    relaxed = -jxx * hs >= RELAX
                    if lat and relaxed:
                        h_off = _off_bound(hs, off)
                    if off > 1.0 and (F0[X] * F2[X] < 0.0 or relaxed):
                        err = max(err, 8.0)
                if err <= 1.0:
                    shorter = _to_stop(y[X], yt[X], xe, hs, tries)
                    if shorter == 0.0:
                        if tries > 0:
                            snapped = _snap(y[X], yt, xe)
                        break
                    if tries == 0:
                        h_land = hs
                    tries += 1
                    hs = shorter
                    last = False
                    continue
                if reuse:        # rejected on a kept Jacobian: retake it, same step size
                    redo = True
                    break
                hs = min(hs * shrink_factor(err, 0.1), max(0.1 * hs, h_off))
                h = hs
                last = False
                if steps >= max_steps:
                    return MAX_STEPS, row, steps
            if redo:
                js[J_FRESH] = 1.0
                continue
            if row >= nrec:
                return FULL, row, steps
            t = t_end if last else t + hs
            clipped = _land(y, yt, xe, last, v0[seg] + vs[seg] * (t_end - tb[seg]),
                            f0[seg] + fs[seg] * (t_end - tb[seg]), NY, hi) or snapped
            if par[P_DM] > 0.0:
                _replay(y, tab, par, xe)
            # the last stage is f at the new state: the next step's start (first same as
            # last), unless the inputs moved (a breakpoint), a stop clipped it or held it
            have = not (clipped or last or mode == HELD)
            if have or (not clipped and mode == FREE and vs[seg] == 0.0 and fs[seg] == 0.0):
                # the last stage is at y (have; or a breakpoint of constant inputs)
                Fe, I = Fe2, I2
                if lat and I != I:
                    I = _lattice_current(tab, par, yt, F2[X], vd, rw, k1, n, NY)
            else:
                Fe, I, _, _, _, _, _ = rhs(y, W, vd, tab, par, law, lawp, k1, rw, pt, AUTO, Jb0)
            if have:
                _carry(ft, F2, Jn, Jn2, rw0, rw, par, n, hi)
                ka, ra, kb, rb, fb = ka2, ra2, kb2, rb2, fb2
            _record(rec, row, t, y, I, Fe, NY)
            row += 1
            # held on a stop the stroke is fixed and the charges' rates are linear: their
            # error estimate is trusted to grow the step up to GROW_HELD (from the landing's
            # step, a unipolar train's held half period took 5 steps at GROW_MAX)
            h_new = min(hs * grow_factor(err, GROW_HELD if mode == HELD else GROW_MAX), h_off)
            if lat and tries > 0:
                # landed on a stop: the next steps need not start from the shortened one (a
                # 10 Hz train spent a third of its steps growing back from 1e-9 s on the stop)
                h_new = max(h_new, h_land)
            h = max(h, h_new) if last else h_new
            if not _finite(y, NY):
                return NONFINITE, row, steps
    return OK, row, steps


@njit(cache=True)
def _phase_offset(y, g, W, tab, par, law, lawp, a, b, yt, rw, pt, NY, Jb0):
    """y's charges and polarizations += their input gains times g (V s): the gains are the
    held rates' change from 0 V to 1 V (on V_d too behind R_s) in averaged mode at the mean
    square voltage W, where the rates are linear in V (the law's conductance at the RMS
    field)."""
    for i in range(NY):
        yt[i] = y[i]
    yt[NY - 2] = 0.0
    if par[P_RS] > 0.0:
        yt[VD] = 0.0
    rhs(yt, W, 0.0, tab, par, law, lawp, a, rw, pt, HELD, Jb0)
    yt[NY - 2] = 1.0
    if par[P_RS] > 0.0:
        yt[VD] = 1.0
    rhs(yt, W, 0.0, tab, par, law, lawp, b, rw, pt, HELD, Jb0)
    for i in range(QF, NY - 2):
        if i != SM:
            y[i] += (b[i] - a[i]) * g


@njit(cache=True, inline="always")
def _record(rec, row, t, y, I, Fe, NY):
    rec[row, R_T], rec[row, R_X], rec[row, R_V], rec[row, R_QF], rec[row, R_PF] = t, y[X], y[VEL], y[QF], y[PF]
    rec[row, R_VD], rec[row, R_VOLT], rec[row, R_F], rec[row, R_I], rec[row, R_FE] = y[VD], y[NY - 2], y[NY - 1], I, Fe


@njit(cache=True)
def evaluate(y, W, vdot, tab, par, law, lawp, ydot, mode):
    """rhs for callers outside the integrator (python-control): returns (force, current)."""
    rw = np.empty(tab.shape[1] + 1)        # + 1: lattice_row's k0
    pt = np.empty(6)
    Fe, I, _, _, _, _, _ = rhs(y, W, vdot, tab, par, law, lawp, ydot, rw, pt, mode, np.empty((0, 4)))
    return Fe, I


@njit(cache=True)
def pi_loop(y0, tab, par, law, lawp, sc, rtol, ctl, n, half, max_steps, out):
    """A sampled PI loop on the stroke closed around the surrogate, all compiled (the
    fast closed-loop path: reduced.holding.simulate_hold_surrogate). Every dt: read the
    stroke, set the amplitude A = v_ff + kp e + integral (clamped to [0, v_max], the
    integral frozen while clamped against the error), apply +-A (the polarity flips
    every `half` steps; half = 0: DC) and the force F over [k dt, (k + 1) dt]; n steps,
    n + 1 reads (the last: no step after it).
    ctl = [x_ref, kp, ki, v_ff, v_max, dt, F]. out[k] = (t_k, x_k, A_k, V_k, I_k): the
    stroke and the source current read at the step's start. Returns (status, steps taken by
    the loop, integrator steps, y). One workspace serves every sample (_workspace)."""
    n_ = int(par[P_N])
    NY = NODE0 + 2 * n_ + 2
    x_ref, kp, ki, v_ff, v_max, dt, F = ctl[0], ctl[1], ctl[2], ctl[3], ctl[4], ctl[5], ctl[6]
    tb = np.empty(2)
    v0 = np.empty(1)
    vs = np.zeros(1)
    f0 = np.empty(1)
    fs = np.zeros(1)
    w2 = np.empty(1)
    gof = np.zeros((1, 2))
    rec = np.empty((4096, NREC))
    ws = _workspace(tab, par)
    # the lattice form keeps its Jacobian across the samples (_kept_jacobian's near): its
    # kept core columns are the stroke's alone (the points' blocks are retaken every step),
    # and a 10 Hz hold tracked within 1 % of the retaken one's RMS in 16 % less time. The
    # charge family's layer and wakes are core states: kept, its hold's RMS nearly doubled
    js = ws[WS_JS]
    js[J_FRESH], js[J_USES], js[J_M], js[J_V] = 1.0, 0.0, -1.0, 0.0
    js[J_NEAR] = 1.0 if par[P_LAT] > 0.0 else 0.0
    y = y0.copy()
    acc = 0.0
    total = 0
    I = 0.0
    # each sample restarts the integrator: with a first step of a whole sample, a hold
    # at rest takes one step per sample (a rejected one halves it, as always)
    h0 = dt
    for k in range(n + 1):
        x = min(max(y[X], 0.0), par[P_XE])
        e = x_ref - x
        a_new = acc + ki * dt * e
        A = v_ff + kp * e + a_new
        if A > v_max:
            A = v_max
            if e < 0.0:
                acc = a_new
        elif A < 0.0:
            A = 0.0
            if e > 0.0:
                acc = a_new
        else:
            acc = a_new
        sgn = 1.0
        if half > 0 and (k // half) % 2 == 1:
            sgn = -1.0
        V = sgn * A
        out[k, 0], out[k, 1], out[k, 2], out[k, 3], out[k, 4] = k * dt, x, A, V, I
        if k == n:
            break
        tb[0], tb[1] = k * dt, (k + 1) * dt
        v0[0], f0[0], w2[0] = V, F, V * V
        y[NY - 2], y[NY - 1] = V, F
        status, rows, steps = _integrate(tb, v0, vs, f0, fs, w2, gof, y, tab, par, law, lawp, sc, rtol, h0, rec,
                                         max_steps, ws)
        total += steps
        if status != OK:
            return status, k, total, y
        I = rec[rows - 1, R_I]
    return OK, n, total, y
