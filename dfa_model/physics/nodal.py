"""Scheme "continuum" (default): nodal, piecewise-linear interface charge.

States q_i at the N material points; q(s) is interpolated linearly, so the charge at
the zipping front, and with it the force, is continuous as the front moves (with q
uniform per element the front's crossing of each element boundary made the stroke
jerk and convergence in N first-order and oscillatory). Charge rates are the Galerkin
projection of J_l - J_f on the hat functions with a lumped (diagonal) mass:

    m_i dq_i/dt = int phi_i(s) [J_l(E_l(s)) - sigma_f(s)/tau_f] ds,
    sigma_l(s) = A(s)/u(s), A = eps_l V - T0 q(s), u = t_l + T0, sigma_f = sigma_l + q,

and F_e = w/(2 eps_l) D int A^2 (dt_l/dp)/u^2 ds. Element integrals: closed form on
fully zipped elements (constant law), 2-3 point Gauss-Legendre on zipped parts, Gauss in
ln(s - l_z + c) graded towards the front where u varies strongly across the element, and
plain 2-4 point Gauss where it varies little. The static force agrees with the
closed-form integrals of the continuum-p0 scheme to 2e-7 relative for the V-shaped gap.

The Jacobian in q is tridiagonal (analytic); with the stroke row and column it is a
bordered tridiagonal system, solved in O(N) by the Thomas algorithm and a Schur
complement for the mechanical unknowns.
"""
from __future__ import annotations

import math

import numpy as np
from .._jit import njit

from .equations import (B, C_LAYOUT, C_M, C_NBORD, C_POL, C_RS, CHI_P, DS, EPS_L, MASS, R_S, T0, TAU_F, TAU_P, U0, W,
                        X_E, XSC,
                        j_and_slope, j_of_E, mech_jacobian,
                        mech_rhs, stroke_velocity, write_outputs)
from .kinematics import V_SHAPED, front_slope, kin_eval, profile

# Gauss-Legendre rules of 2, 3, 4, 6 and 8 points, padded into one table
GN = np.array([2, 3, 4, 6, 8])
GXS = np.zeros((5, 8))
GWS = np.zeros((5, 8))
for _i, _n in enumerate(GN):
    GXS[_i, :_n], GWS[_i, :_n] = np.polynomial.legendre.leggauss(_n)
# order of the graded rule by the span L of ln(s - l_z + c) over the element: the
# integrands behave like exp(-y), for which these keep the relative error < 1e-5
SPAN = np.array([0.15, 0.6, 1.5, 3.0])
NQMAX = 11
NWORK = 48    # scratch size for the kernels (>= 4 NQMAX)


@njit(cache=True, _nrt=False, inline='always')
def elem_nodes(layout, const, geo, mat, kin, sa, sb, xi, wt, uu, dd):
    """Quadrature nodes of element [sa, sb]: local coordinate xi in [0, 1], weight
    (m), u = t_l + T0 and dt_l/dp. Returns the number of nodes."""
    ds = sb - sa
    u0 = mat[U0]
    lz = kin[0]
    n = 0
    ze = min(sb, lz)
    if ze > sa:
        # zipped part: u = u0 and no force; integrands are polynomials of degree <= 2
        # in s for a constant law (2 points are exact), smooth otherwise (3 points)
        h = 0.5 * (ze - sa)
        m = 0.5 * (ze + sa)
        r = 0 if const else 1
        for i in range(GN[r]):
            s = m + h * GXS[r, i]
            xi[n] = (s - sa) / ds
            wt[n] = h * GWS[r, i]
            uu[n] = u0
            dd[n] = 0.0
            n += 1
    if sb > lz and lz < geo[2]:
        sga = max(sa, lz) - lz
        sgb = sb - lz
        c = u0 / front_slope(layout, kin)
        ratio = (sgb + c) / (sga + c)
        if ratio < 1.5:
            # far from the front u changes little across the element: plain Gauss in s
            # (error ~ ((ratio-1)/(ratio+1))^(2n) < 6e-6 with these orders), no exp/log
            r = 0 if ratio < 1.1 else (1 if ratio < 1.2 else 2)
            h = 0.5 * (sgb - sga)
            m = 0.5 * (sgb + sga)
            for i in range(GN[r]):
                sg = m + h * GXS[r, i]
                gap, dgap = profile(layout, geo, kin, sg)
                xi[n] = (sg + lz - sa) / ds
                wt[n] = h * GWS[r, i]
                uu[n] = u0 + gap
                dd[n] = dgap
                n += 1
            return n
        ya = math.log(sga + c)
        yb = math.log(sgb + c)
        hy = 0.5 * (yb - ya)
        ym = 0.5 * (yb + ya)
        r = 0
        while r < 4 and yb - ya > SPAN[r]:
            r += 1
        for i in range(GN[r]):
            ey = math.exp(ym + hy * GXS[r, i])
            sg = ey - c
            gap, dgap = profile(layout, geo, kin, sg)
            xi[n] = (sg + lz - sa) / ds
            wt[n] = hy * GWS[r, i] * ey
            uu[n] = u0 + gap
            dd[n] = dgap
            n += 1
    elif sb > lz:                                 # beyond the electrode end: all zipped
        pass
    return n


@njit(cache=True, _nrt=False, inline='always')
def _g(law, lawp, const, mat, V, qs, u, itau_l, itau_f):
    """Pointwise J_l - J_f and its derivative with respect to q(s)."""
    eps_l, t0 = mat[EPS_L], mat[T0]
    A = eps_l * V - t0 * qs
    iu = 1.0 / u
    sl = A * iu
    if const:
        dJ = itau_l
        Jl = sl * dJ
    else:
        Jl, dJ = j_and_slope(law, lawp, sl / eps_l, eps_l)
    g = Jl - (sl + qs) * itau_f
    t0u = t0 * iu
    dg = -dJ * t0u - (1.0 - t0u) * itau_f
    return A, sl, Jl, g, dg


@njit(cache=True, _nrt=False)
def rhs_p1(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, jac, tri, jbe, work):
    """ydot = f(y); with jac, also the tridiagonal dq'/dq (tri[i] = [sub, diag, sup])
    and the force derivatives jbe[i] = dT/dq_i. Returns F_e. work: scratch, >= 4 NQMAX.

    With the liquid's fast relaxation (cfg[C_POL]; physics guide 'Polarization branch')
    the states are [q'_i, then P_i]: q' = q + P is the charge the electrostatics see (the
    bound charge of the polarization P acts at the interfaces like free charge), and

        dP_i/dt = (chi_p (eps_l V - T0 q'_i)/w_i - P_i)/tau_p,
        dq'_i/dt = <J_l - J_f>_i + dP_i/dt,

    <.>_i the lumped Galerkin projection, w_i the point's weight (_weights: u averaged
    over its hat), and P rebuilt between the points with P (u + chi_p T0) linear (_element). The
    branch's energy t_l P^2/(2 chi_p eps_l) depends on the gap, so P adds to the force.
    tri[:, 3:6] then receives d(dP/dt)/dq' (diagonal), tri[:, 9:12] d(dq'/dt)/dP through
    the seen charge, and jbe[nq + i] = dT/dP_i.

    With a series resistance R_s (cfg[C_RS]; README 'Series resistance') the last state
    is the device's voltage V_d, which the elements see in place of the source's V:
    w (eps_l V_d' int 1/u + X) = (V - V_d)/R_s, X the rest of the device current
    (conduction, dq'/dt and dP/dt terms, and the gap's motion). jbe[2 nq:3 nq] receives
    int phi_i/u, jbe[3 nq] d(V_d')/d(x') (see jacobian_p1); with the branch too,
    jbe[3 nq + 1:4 nq + 1] the rebuilt profile's share of the device current per unit
    dP_i/dt. jbe: >= 4 nq + 1.

    The element integrals are in _zipped_element (closed form), _element_fast (the
    constant law's hot path) and _element (any law, the Jacobian, the branch); the
    lumped mass, the branch's rates and the device current in _lumped."""
    nbord, M = cfg[C_NBORD], cfg[C_M]
    layout = cfg[C_LAYOUT]
    const = law == 0
    pol = cfg[C_POL] == 1
    rs = cfg[C_RS] == 1
    nlast = y.shape[0] - 1
    Vd = y[nlast] if rs else V
    m1s = 0.0          # int 1/u
    SJ = 0.0           # int J_l
    SAD = 0.0          # int sigma_l (dt_l/dp)/u
    ds = mat[DS]
    t0 = mat[T0]
    kin_eval(layout, geo, y[0], kin)
    nq = M + 1
    po = nbord + nq                   # offset of the polarization states
    _clear_rates(ydot, tri, jbe, nbord, nq, po, pol, rs, jac)
    SM = 0.0          # the reconstruction's motion term in the device current (R_s)
    xi = work[0:NQMAX]
    wt = work[NQMAX:2 * NQMAX]
    uu = work[2 * NQMAX:3 * NQMAX]
    dd = work[3 * NQMAX:4 * NQMAX]
    T = 0.0
    lz = kin[0]
    itau_f = 1.0 / mat[TAU_F]
    itau_l = 1.0 / (lawp[0] * mat[EPS_L]) if const else 0.0
    # fully zipped elements with a constant law: g = a0 + a1 q(s) exactly (u = u0)
    c_lf = 0.0
    a0 = 0.0
    a1 = 0.0
    epsV = mat[EPS_L] * Vd
    iu0 = 1.0 / mat[U0]
    if const:
        c_lf = 1.0 / (lawp[0] * mat[EPS_L]) - 1.0 / mat[TAU_F]
        a0 = epsV * c_lf / mat[U0]
        a1 = -(t0 * c_lf / mat[U0] + 1.0 / mat[TAU_F])
    prev = (0.0, 0.0, 0.0, 0.0)        # the branch's weights, rolled along the elements (_weights)
    cur = _u_elem(layout, geo, mat, kin, 0.0, ds) if pol else prev
    for e in range(M):
        dda = 0.0
        ddb = 0.0
        if pol:     # ydot[po + j] holds w_j until _lumped (read by _element)
            ydot[po + e], dda, ydot[po + e + 1], ddb, nxt = _weights(layout, geo, mat, kin, e, M, prev, cur)
            prev, cur = cur, nxt
        # (with the branch both points' weights must be u0: the next element zipped too)
        if const and (e + 1 + pol) * ds <= lz:
            m1s, SJ = _zipped_element(e, y, ydot, tri, jbe, nbord, nq, rs, jac, ds, t0, epsV, iu0, a0, a1,
                                      itau_l, m1s, SJ)
            continue
        nn = elem_nodes(layout, const, geo, mat, kin, e * ds, (e + 1) * ds, xi, wt, uu, dd)
        if const and not jac and not pol:
            T, m1s, SJ, SAD = _element_fast(e, nn, xi, wt, uu, dd, y, ydot, jbe, nbord, nq, rs, t0, epsV, c_lf, itau_f,
                                            itau_l, T, m1s, SJ, SAD)
        else:
            T, m1s, SJ, SAD, SM = _element(e, nn, xi, wt, uu, dd, law, lawp, const, mat, Vd, y, ydot, tri, jbe, nbord,
                                           nq, po, pol, rs, jac, t0, T, m1s, SJ, SAD, (dda, ddb), SM)
    X = _lumped(y, ydot, tri, jbe, nbord, nq, po, pol, rs, jac, ds, t0, mat[CHI_P], 1.0 / mat[TAU_P], SJ, epsV)
    Fe = mat[W] / (2.0 * mat[EPS_L]) * kin[1] * T
    mech_rhs(cfg, mat, F, y, Fe, ydot)
    if rs:
        kap = kin[1] * SAD / (mat[EPS_L] * m1s)     # d(V_d')/d(x'): the moving gap's current
        X -= kin[1] * stroke_velocity(cfg, mat, y, ydot) * (SAD - SM)
        ydot[nlast] = ((V - Vd) / (mat[W] * mat[R_S]) - X) / (mat[EPS_L] * m1s)
        jbe[3 * nq] = kap
    return Fe


@njit(cache=True, _nrt=False, inline='always')
def _clear_rates(ydot, tri, jbe, nbord, nq, po, pol, rs, jac):
    """Zero the charge (and branch) rates and the Jacobian pieces rhs_p1 accumulates."""
    for i in range(nq):
        ydot[nbord + i] = 0.0
        if jac:
            tri[i, 0] = 0.0
            tri[i, 1] = 0.0
            tri[i, 2] = 0.0
            jbe[i] = 0.0
            if pol:
                for c in range(3, 6):
                    tri[i, c] = 0.0
                for c in range(9, 12):
                    tri[i, c] = 0.0
                jbe[nq + i] = 0.0
        if rs:
            jbe[2 * nq + i] = 0.0
            if pol:
                jbe[3 * nq + 1 + i] = 0.0


@njit(cache=True, _nrt=False, inline='always')
def _zipped_element(e, y, ydot, tri, jbe, nbord, nq, rs, jac, ds, t0, epsV, iu0, a0, a1, itau_l, m1s, SJ):
    """A fully zipped element, constant law: g = a0 + a1 q(s) exactly (u = u0), in
    closed form (the branch's reconstruction is linear there). Returns the running
    int 1/u and int J_l."""
    qa = y[nbord + e]
    qb = y[nbord + e + 1]
    ydot[nbord + e] += ds * (0.5 * a0 + a1 * (qa / 3.0 + qb / 6.0))
    ydot[nbord + e + 1] += ds * (0.5 * a0 + a1 * (qa / 6.0 + qb / 3.0))
    if jac:
        tri[e, 1] += a1 * ds / 3.0
        tri[e, 2] += a1 * ds / 6.0
        tri[e + 1, 0] += a1 * ds / 6.0
        tri[e + 1, 1] += a1 * ds / 3.0
    if rs:
        m1s += ds * iu0
        jbe[2 * nq + e] += 0.5 * ds * iu0
        jbe[2 * nq + e + 1] += 0.5 * ds * iu0
        SJ += itau_l * ds * iu0 * (epsV - 0.5 * t0 * (qa + qb))
    return m1s, SJ


@njit(cache=True, _nrt=False, inline='always')
def _element_fast(e, nn, xi, wt, uu, dd, y, ydot, jbe, nbord, nq, rs, t0, epsV, c_lf, itau_f, itau_l, T, m1s, SJ,
                  SAD):
    """The hot path (constant law, no Jacobian, no branch): g = c_lf sigma_l - q/tau_f
    at the element's quadrature nodes. Returns the running force integral T and the
    series resistance's integrals."""
    qa = y[nbord + e]
    qb = y[nbord + e + 1]
    b0 = 0.0
    b1 = 0.0
    dq = qb - qa
    for k in range(nn):
        p1 = xi[k]
        qs = qa + dq * p1
        sl = (epsV - t0 * qs) / uu[k]
        wg = wt[k] * (c_lf * sl - qs * itau_f)
        b1 += wg * p1
        b0 += wg - wg * p1
        T += wt[k] * dd[k] * sl * sl
        if rs:
            wu = wt[k] / uu[k]
            m1s += wu
            jbe[2 * nq + e] += wu * (1.0 - p1)
            jbe[2 * nq + e + 1] += wu * p1
            SJ += wt[k] * sl * itau_l
            SAD += wu * dd[k] * sl
    ydot[nbord + e] += b0
    ydot[nbord + e + 1] += b1
    return T, m1s, SJ, SAD


@njit(cache=True, _nrt=False, inline='always')
def _u_elem(layout, geo, mat, kin, sa, sb):
    """int phi_a u and int phi_b u over element [sa, sb] (u = t_l + T0), and the same of
    du/dl_z at fixed s: exact on the zipped part, 3-point Gauss on the rest (u is smooth
    there; 2 points for the V-shaped gap, linear in s: exact)."""
    ds = sb - sa
    u0 = mat[U0]
    lz = kin[0]
    ze = max(sa, min(sb, lz)) if lz < geo[2] else sb     # the zipped part is [sa, ze]
    Ia = 0.0
    Ib = 0.0
    Ja = 0.0
    Jb = 0.0
    if ze > sa:
        L = ze - sa
        Ib = u0 * L * L / (2.0 * ds)
        Ia = u0 * L - Ib
    if sb > ze:
        h = 0.5 * (sb - ze)
        m = 0.5 * (sb + ze)
        r = 0 if layout == V_SHAPED else 1
        for i in range(GN[r]):
            s = m + h * GXS[r, i]
            gap, dgap = profile(layout, geo, kin, s - lz)
            w = h * GWS[r, i]
            pb = (s - sa) / ds
            Ia += w * (1.0 - pb) * (u0 + gap)
            Ib += w * pb * (u0 + gap)
            Ja += w * (1.0 - pb) * dgap
            Jb += w * pb * dgap
    return Ia, Ib, Ja, Jb


@njit(cache=True, _nrt=False, inline='always')
def _mass(i, nq, ds):
    """The lumped mass of point i, int phi_i."""
    return ds if 0 < i < nq - 1 else 0.5 * ds


@njit(cache=True, _nrt=False, inline='always')
def _weights(layout, geo, mat, kin, e, M, prev, cur):
    """The branch's weights at element e's two points and their derivatives in l_z:
    (w_a, dw_a/dl_z, w_b, dw_b/dl_z, element e + 1's integrals). A weight is u averaged
    over the point's hat: smooth in l_z as the front crosses the point (u there is not:
    weights with a kink in time cost every crossing ~30 rejected steps). prev, cur:
    _u_elem of elements e - 1 (zeros for e = 0) and e; the caller rolls them along."""
    ds = mat[DS]
    nxt = _u_elem(layout, geo, mat, kin, (e + 1) * ds, (e + 2) * ds) if e + 1 < M else (0.0, 0.0, 0.0, 0.0)
    ma = _mass(e, M + 1, ds)
    mb = _mass(e + 1, M + 1, ds)
    return (prev[1] + cur[0]) / ma, (prev[3] + cur[2]) / ma, (cur[1] + nxt[0]) / mb, (cur[3] + nxt[2]) / mb, nxt


@njit(cache=True, _nrt=False, inline='always')
def _element(e, nn, xi, wt, uu, dd, law, lawp, const, mat, Vd, y, ydot, tri, jbe, nbord, nq, po, pol, rs, jac, t0,
             T, m1s, SJ, SAD, ddab, SM):
    """An element in general (any law; the Jacobian; the polarization branch) at its
    quadrature nodes. Returns the running force integral T, the series resistance's
    integrals and SM, the branch reconstruction's motion term in the device current.

    The branch (rhs_p1) is rebuilt between its material points as
    P(s) = sum_j phi_j P_j (w_j + chi T0)/(u(s) + chi T0), w_j the point's weight
    (_weights: u averaged over its hat), and each P_j relaxes towards
    chi (eps_l V - T0 q'_j)/w_j (_lumped). Where P follows the field, P_j (w_j + chi T0)
    = chi (eps_l V - T0 q_j), q the free charge, so the rebuilt profile is
    chi (eps_l V - T0 q(s))/(u(s) + chi T0): exact however sharply u rises ahead of the
    front, whatever the weights (a P linear between the points was not: its error
    converged slowly in N). The electrostatics see q'(s) = sum_j phi_j (q'_j - P_j) + P(s).
    The branch's energy t_l P^2/(2 chi eps_l) adds to the force. ydot[po + j] holds w_j
    here, ddab the weights' dw/dl_z (with R_s). Few arguments: a call of more than 30
    compiles to one with *args, which numba cannot inline."""
    itau_f = 1.0 / mat[TAU_F]
    itau_l = 1.0 / (lawp[0] * mat[EPS_L]) if const else 0.0
    ichi = 1.0 / mat[CHI_P] if pol else 0.0
    cT = mat[CHI_P] * t0 if pol else 0.0
    dda, ddb = ddab
    qa = y[nbord + e]
    qb = y[nbord + e + 1]
    b0 = 0.0
    b1 = 0.0
    Pa = y[po + e] if pol else 0.0
    Pb = y[po + e + 1] if pol else 0.0
    ua = ydot[po + e] if pol else 0.0
    ub = ydot[po + e + 1] if pol else 0.0
    for k in range(nn):
        p1 = xi[k]
        p0 = 1.0 - p1
        qs = qa * p0 + qb * p1
        if pol:
            iw = 1.0 / (uu[k] + cT)
            rA = (ua + cT) * iw
            rB = (ub + cT) * iw
            PA = Pa * p0
            PB = Pb * p1
            Ps = PA * rA + PB * rB
            qs += PA * (rA - 1.0) + PB * (rB - 1.0)
        A, sl, Jl, g, dg = _g(law, lawp, const, mat, Vd, qs, uu[k], itau_l, itau_f)
        b0 += wt[k] * p0 * g
        b1 += wt[k] * p1 * g
        if rs:
            wu = wt[k] / uu[k]
            m1s += wu
            jbe[2 * nq + e] += wu * p0
            jbe[2 * nq + e + 1] += wu * p1
            SJ += wt[k] * Jl
            SAD += wu * dd[k] * sl
            if pol:
                # the device current's share of the rebuilt P beyond the linear one:
                # dP/dt (1 - T0/u) per unit length, its rates (K_j) and its motion (SM)
                c1 = wt[k] * (1.0 - t0 / uu[k])
                jbe[3 * nq + 1 + e] += c1 * p0 * (rA - 1.0)
                jbe[3 * nq + 2 + e] += c1 * p1 * (rB - 1.0)
                SM += c1 * iw * (PA * (dda - dd[k] * rA) + PB * (ddb - dd[k] * rB))
        if dd[k] != 0.0:
            wdu = wt[k] * dd[k] * (sl / A if A != 0.0 else 1.0 / uu[k]) ** 2   # w dt_l/dp / u^2
            T += wdu * A * A
        else:
            wdu = 0.0
        if pol:
            # the branch's energy t_l P^2/(2 chi eps_l): in units of the field term
            # (A^2 (dt_l/dp)/u^2 carries 1/(2 eps_l)), + (dt_l/dp) P^2/chi
            T += wt[k] * dd[k] * Ps * Ps * ichi
        if jac:
            wdg = wt[k] * dg
            tri[e, 1] += wdg * p0 * p0
            tri[e, 2] += wdg * p0 * p1
            tri[e + 1, 0] += wdg * p1 * p0
            tri[e + 1, 1] += wdg * p1 * p1
            dT = wdu * 2.0 * A * (-t0)
            jbe[e] += dT * p0
            jbe[e + 1] += dT * p1
            if pol:
                # d(dq'/dt)/dP through the seen charge (tri[:, 9:12])
                ga = wdg * p0 * (rA - 1.0)
                gb = wdg * p1 * (rB - 1.0)
                tri[e, 10] += p0 * ga
                tri[e, 11] += p0 * gb
                tri[e + 1, 9] += p1 * ga
                tri[e + 1, 10] += p1 * gb
                dTP = wt[k] * dd[k] * 2.0 * Ps * ichi
                jbe[nq + e] += dT * p0 * (rA - 1.0) + dTP * p0 * rA
                jbe[nq + e + 1] += dT * p1 * (rB - 1.0) + dTP * p1 * rB
    ydot[nbord + e] += b0
    ydot[nbord + e + 1] += b1
    return T, m1s, SJ, SAD, SM


@njit(cache=True, _nrt=False, inline='always')
def _lumped(y, ydot, tri, jbe, nbord, nq, po, pol, rs, jac, ds, t0, chi, itp, SJ, epsV):
    """Divide the projections by the lumped mass; the branch's rates at its material
    points, dP_j/dt = (chi (eps_l V - T0 q'_j)/w_j - P_j)/tau_p, chi sigma_l there with
    u replaced by the point's weight w_j (added to dq'/dt; ydot[po + j] holds w_j on
    entry). Returns X, the device current without its dV_d/dt and gap-motion terms
    (series resistance; SJ = int J_l)."""
    X = SJ
    for i in range(nq):
        mi = _mass(i, nq, ds)
        ydot[nbord + i] /= mi
        if jac:
            tri[i, 0] /= mi
            tri[i, 1] /= mi
            tri[i, 2] /= mi
        if pol:
            iu = 1.0 / ydot[po + i]
            Pd = (chi * (epsV - t0 * y[nbord + i]) * iu - y[po + i]) * itp
            ydot[po + i] = Pd
            ydot[nbord + i] += Pd
            if rs:
                X += Pd * (mi + jbe[3 * nq + 1 + i])
            if jac:
                for c in range(9, 12):
                    tri[i, c] /= mi
                tri[i, 4] = -chi * t0 * iu * itp
                tri[i, 1] += tri[i, 4]
        if rs:
            X -= t0 * ydot[nbord + i] * jbe[2 * nq + i]
    return X


@njit(cache=True, _nrt=False)
def jacobian_p1(cfg, geo, mat, law, lawp, V, F, y, f0, tri, Jeb, Jbe, Jbb, kin, tmp, ytmp, work, jbe):
    """Bordered tridiagonal Jacobian: tri (dq'/dq), Jeb[:, 0] (dq'/dx), Jbe[:, 0]
    (d of the force-bearing mechanical rate / dq), Jbb. With polarization also
    tri[:, 3:6] (dP'/dq), Jeb[:, 1] (dP'/dx) and Jbe[:, 1] (d force rate / dP); the
    P-diagonal is -1/tau_p (in factor_p1). f0 receives f(y)."""
    nbord, M = cfg[C_NBORD], cfg[C_M]
    nq = M + 1
    pol = cfg[C_POL] == 1
    rhs_p1(cfg, geo, mat, law, lawp, V, F, y, f0, kin, True, tri, jbe, work)
    D = kin[1]
    cF = mat[W] / (2.0 * mat[EPS_L])
    den = mat[B] if nbord == 1 else mat[MASS]
    for i in range(nq):
        Jbe[i, 0] = -cF * D * jbe[i] / den
        if pol:
            Jbe[i, 1] = -cF * D * jbe[nq + i] / den
    hx = 1e-7 * mat[XSC]
    if y[0] + hx > mat[X_E]:      # at the upper stop: difference towards the interior
        hx = -hx
    for i in range(y.shape[0]):
        ytmp[i] = y[i]
    ytmp[0] += hx
    rs = cfg[C_RS] == 1
    kap = jbe[3 * nq] if rs else 0.0      # from the unperturbed evaluation above
    rhs_p1(cfg, geo, mat, law, lawp, V, F, ytmp, tmp, kin, False, tri, jbe, work)
    for i in range(nq):
        Jeb[i, 0] = (tmp[nbord + i] - f0[nbord + i]) / hx
        if pol:
            Jeb[i, 1] = (tmp[nbord + nq + i] - f0[nbord + nq + i]) / hx
    mech_jacobian(cfg, mat, tmp, f0, hx, Jbb)
    # Jbb[:, 3]: how strongly each border row couples to the elements, as multiples of
    # the force-bearing row (1 there): the border rows see the elements only through it
    for a in range(Jbb.shape[0]):
        Jbb[a, 3] = 0.0
    Jbb[nbord - 1, 3] = 1.0
    if rs:
        # border state V_d (index nbord of the border block; the last state). Its row
        # depends on the elements through the stroke's velocity (kap times the force
        # row when massless); the elements' dependence on V_d (~1/tau) is left to
        # Newton's iteration, which the full residual keeps exact
        n = y.shape[0]
        d = nbord
        Jbb[d, 0] = (tmp[n - 1] - f0[n - 1]) / hx
        if nbord == 2:
            Jbb[d, 1] = kap
        else:
            Jbb[d, 3] = kap
        hv = math.copysign(1e-6 * max(abs(y[n - 1]), 100.0), y[n - 1])   # odd in V: V -> -V symmetric
        ytmp[0] = y[0]
        ytmp[n - 1] = y[n - 1] + hv
        rhs_p1(cfg, geo, mat, law, lawp, V, F, ytmp, tmp, kin, False, tri, jbe, work)
        for a in range(nbord):
            Jbb[a, d] = (tmp[a] - f0[a]) / hv
        Jbb[d, d] = (tmp[n - 1] - f0[n - 1]) / hv
        jbe[3 * nq] = kap
    kin_eval(cfg[C_LAYOUT], geo, y[0], kin)
    return nbord - 1


@njit(cache=True, _nrt=False)
def _thomas(cp, dinv, tri, tc, gh, r, roff, out, ooff, nq):
    """Solve (I - gh tri[:, tc:tc+3]) z = r[roff:] with the stored factorization."""
    # forward
    prev = 0.0
    for i in range(nq):
        a = -gh * tri[i, tc]
        z = (r[roff + i] - a * prev) * dinv[i]
        out[ooff + i] = z
        prev = z
    for i in range(nq - 2, -1, -1):
        out[ooff + i] -= cp[i] * out[ooff + i + 1]


@njit(cache=True, _nrt=False, inline='always')
def _tri_dot(tri, tc, v, voff, i, nq):
    """Row i of the tridiagonal tri[:, tc:tc+3] times v[voff:voff + nq]."""
    acc = tri[i, tc + 1] * v[voff + i]
    if i > 0:
        acc += tri[i, tc] * v[voff + i - 1]
    if i < nq - 1:
        acc += tri[i, tc + 2] * v[voff + i + 1]
    return acc


@njit(cache=True, _nrt=False, inline='always')
def _beta(mat, gh):
    """Elimination of the polarization states: W_PP = (1 + gh/tau_p) I, beta its inverse."""
    return 1.0 / (1.0 + gh / mat[TAU_P])


@njit(cache=True, _nrt=False)
def _pol_back(tri, gh, beta, rP, roff, zq, zoff, out, ooff, nq):
    """out = beta (r_P + gh T_Pq z_q): the P part of W^-1 r once z_q is known."""
    for i in range(nq):
        acc = tri[i, 4] * zq[zoff + i]
        if i > 0:
            acc += tri[i, 3] * zq[zoff + i - 1]
        if i < nq - 1:
            acc += tri[i, 5] * zq[zoff + i + 1]
        out[ooff + i] = beta * (rP[roff + i] + gh * acc)


@njit(cache=True, _nrt=False)
def factor_p1(cfg, mat, gh, tri, Jeb, Jbe, Jbb, fb, cp, dinv, zeta, S):
    # S: the border's Schur complement (x, v with mass, V_d with a series resistance)
    """Factor W = I - gh J. With polarization the P unknowns are eliminated first
    (W_PP = (1 + gh/tau_p) I): the q' system keeps its tridiagonal form with
    T_eff = T_qq - (1 - beta) T_Pq + gh beta G_P T_Pq (stored in tri[:, 6:9]; T_Pq,
    tri[:, 3:6], is diagonal, G_P = d(dq'/dt)/dP through the seen charge, tri[:, 9:12])."""
    nbord, M = cfg[C_NBORD], cfg[C_M]
    nq = M + 1
    pol = cfg[C_POL] == 1
    tc = 0
    beta = 1.0
    if pol:
        beta = _beta(mat, gh)
        tc = 6
        gb = gh * beta
        for i in range(nq):
            for c in range(3):
                tri[i, 6 + c] = tri[i, c] - (1.0 - beta) * tri[i, 3 + c]
                j = i - 1 + c
                if 0 <= j < nq:
                    tri[i, 6 + c] += gb * tri[i, 9 + c] * tri[j, 4]
    for i in range(nq):
        a = -gh * tri[i, tc]
        b = 1.0 - gh * tri[i, tc + 1]
        c = -gh * tri[i, tc + 2]
        den = b - (a * cp[i - 1] if i > 0 else 0.0)
        dinv[i] = 1.0 / den
        cp[i] = c / den
    # zeta = W_ee^-1 (-gh Jeb)
    for i in range(nq):
        zeta[i, 0] = -gh * Jeb[i, 0]
        if pol:
            zeta[i, 0] -= (1.0 - beta) * (-gh * Jeb[i, 1]) + gh * beta * gh * _tri_dot(tri, 9, Jeb[:, 1], 0, i, nq)
            zeta[i, 1] = -gh * Jeb[i, 1]
    z0 = zeta[:, 0]
    _thomas(cp, dinv, tri, tc, gh, z0, 0, z0, 0, nq)     # in place: each entry is read before written
    if pol:
        z1 = zeta[:, 1]
        _pol_back(tri, gh, beta, z1, 0, z0, 0, z1, 0, nq)   # reads z1[i] before writing it
    nbx = nbord + cfg[C_RS]
    for a in range(nbx):
        for b in range(nbx):
            S[a, b] = (1.0 if a == b else 0.0) - gh * Jbb[a, b]
    acc = 0.0
    for i in range(nq):
        acc += -gh * Jbe[i, 0] * zeta[i, 0]
        if pol:
            acc += -gh * Jbe[i, 1] * zeta[i, 1]
    for a in range(nbx):
        S[a, 0] -= Jbb[a, 3] * acc


@njit(cache=True, _nrt=False, inline='always')
def _cramer3(S, r0, r1, r2):
    """The 3x3 border system S z = r (x, v, V_d) by Cramer's rule."""
    det = (S[0, 0] * (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]) - S[0, 1] * (S[1, 0] * S[2, 2] - S[1, 2] * S[2, 0])
           + S[0, 2] * (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0]))
    z0 = (r0 * (S[1, 1] * S[2, 2] - S[1, 2] * S[2, 1]) - S[0, 1] * (r1 * S[2, 2] - S[1, 2] * r2)
          + S[0, 2] * (r1 * S[2, 1] - S[1, 1] * r2)) / det
    z1 = (S[0, 0] * (r1 * S[2, 2] - S[1, 2] * r2) - r0 * (S[1, 0] * S[2, 2] - S[1, 2] * S[2, 0])
          + S[0, 2] * (S[1, 0] * r2 - r1 * S[2, 0])) / det
    z2 = (S[0, 0] * (S[1, 1] * r2 - r1 * S[2, 1]) - S[0, 1] * (S[1, 0] * r2 - r1 * S[2, 0])
          + r0 * (S[1, 0] * S[2, 1] - S[1, 1] * S[2, 0])) / det
    return z0, z1, z2


@njit(cache=True, _nrt=False)
def solve_p1(cfg, mat, gh, tri, cp, dinv, zeta, Jbe, Jbb, S, fb, r, out):
    nbord, M = cfg[C_NBORD], cfg[C_M]
    nq = M + 1
    pol = cfg[C_POL] == 1
    po = nbord + nq
    if pol:
        beta = _beta(mat, gh)
        for i in range(nq):
            out[nbord + i] = r[nbord + i] - (1.0 - beta) * r[po + i] + gh * beta * _tri_dot(tri, 9, r, po, i, nq)
        _thomas(cp, dinv, tri, 6, gh, out, nbord, out, nbord, nq)
        _pol_back(tri, gh, beta, r, po, out, nbord, out, po, nq)
    else:
        _thomas(cp, dinv, tri, 0, gh, r, nbord, out, nbord, nq)
    acc = 0.0
    for i in range(nq):
        acc += -gh * Jbe[i, 0] * out[nbord + i]
        if pol:
            acc += -gh * Jbe[i, 1] * out[po + i]
    if cfg[C_RS] == 1:
        n = r.shape[0]
        nbx = nbord + 1
        r0 = r[0] - Jbb[0, 3] * acc
        r1 = r[1] - Jbb[1, 3] * acc if nbord == 2 else r[n - 1] - Jbb[1, 3] * acc
        if nbx == 2:
            det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
            dx = (r0 * S[1, 1] - S[0, 1] * r1) / det
            out[0] = dx
            out[n - 1] = (S[0, 0] * r1 - S[1, 0] * r0) / det
        else:
            r2 = r[n - 1] - Jbb[2, 3] * acc
            dx, dv, dvd = _cramer3(S, r0, r1, r2)
            out[0] = dx
            out[1] = dv
            out[n - 1] = dvd
    elif nbord == 1:
        dx = (r[0] - acc) / S[0, 0]
        out[0] = dx
    else:
        rb0 = r[0]
        rb1 = r[1] - acc
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        dx = (rb0 * S[1, 1] - S[0, 1] * rb1) / det
        out[0] = dx
        out[1] = (S[0, 0] * rb1 - S[1, 0] * rb0) / det
    for i in range(nq):
        out[nbord + i] -= zeta[i, 0] * dx
        if pol:
            out[po + i] -= zeta[i, 1] * dx


@njit(cache=True, _nrt=False)
def diagnostics_p1(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, rec, P, work):
    """Outputs and powers (see equations.diagnostics) for the nodal scheme. The
    'intra' power is the Galerkin projection term int 2 t_f E_f (g - q'(s)) ds."""
    nbord, M = cfg[C_NBORD], cfg[C_M]
    layout = cfg[C_LAYOUT]
    const = law == 0
    eps_l, t0, ds, w, tau_f = mat[EPS_L], mat[T0], mat[DS], mat[W], mat[TAU_F]
    kin_eval(layout, geo, y[0], kin)
    D = kin[1]
    v = stroke_velocity(cfg, mat, y, ydot)
    xi = work[0:NQMAX]
    wt = work[NQMAX:2 * NQMAX]
    uu = work[2 * NQMAX:3 * NQMAX]
    dd = work[3 * NQMAX:4 * NQMAX]
    I = 0.0
    C = 0.0
    U = 0.0
    Q = 0.0
    PJ = 0.0
    Pint = 0.0
    T = 0.0
    Emax = 0.0
    itau_l = 1.0 / (lawp[0] * eps_l) if const else 0.0
    itau_f = 1.0 / tau_f
    ieps_l = 1.0 / eps_l
    rs = cfg[C_RS] == 1
    nlast = y.shape[0] - 1
    epsV = eps_l * (y[nlast] if rs else V)         # the electrodes' voltage (V_d behind R_s)
    epsVd = eps_l * (ydot[nlast] if rs else dVdt)
    pol = cfg[C_POL] == 1
    po = nbord + M + 1
    ichi = 1.0 / mat[CHI_P] if pol else 0.0
    cT = mat[CHI_P] * t0 if pol else 0.0
    vD = v * D
    ua = ub = dda = ddb = 0.0
    prev = (0.0, 0.0, 0.0, 0.0)        # the branch's weights, rolled along as in rhs_p1
    cur = _u_elem(layout, geo, mat, kin, 0.0, ds) if pol else prev
    for e in range(M):
        qa, qb = y[nbord + e], y[nbord + e + 1]
        qda, qdb = ydot[nbord + e], ydot[nbord + e + 1]
        dq, dqd = qb - qa, qdb - qda
        Pa = y[po + e] if pol else 0.0
        Pb = y[po + e + 1] if pol else 0.0
        Pda = ydot[po + e] if pol else 0.0
        Pdb = ydot[po + e + 1] if pol else 0.0
        if pol:
            ua, dda, ub, ddb, nxt = _weights(layout, geo, mat, kin, e, M, prev, cur)
            prev, cur = cur, nxt
        nn = elem_nodes(layout, const, geo, mat, kin, e * ds, (e + 1) * ds, xi, wt, uu, dd)
        for k in range(nn):
            p1 = xi[k]
            qs = qa + dq * p1
            qd = qda + dqd * p1
            Ps = 0.0
            Pd = 0.0
            if pol:
                # the rebuilt P (see _element) and its rate at fixed s, with the
                # weights' own motion as the front moves
                p0 = 1.0 - p1
                iw = 1.0 / (uu[k] + cT)
                rA = (ua + cT) * iw
                rB = (ub + cT) * iw
                rdA = vD * (dda - dd[k] * rA) * iw
                rdB = vD * (ddb - dd[k] * rB) * iw
                Ps = Pa * p0 * rA + Pb * p1 * rB
                Pd = Pda * p0 * rA + Pdb * p1 * rB + Pa * p0 * rdA + Pb * p1 * rdB
                qs += Pa * p0 * (rA - 1.0) + Pb * p1 * (rB - 1.0)
                qd += Pda * p0 * (rA - 1.0) + Pdb * p1 * (rB - 1.0) + Pa * p0 * rdA + Pb * p1 * rdB
            u = uu[k]
            iu = 1.0 / u
            A = epsV - t0 * qs
            sl = A * iu
            # no derivative needed here, so the law is evaluated once (not via _g)
            Jl = sl * itau_l if const else j_of_E(law, lawp, sl * ieps_l)
            sf = sl + qs
            g = Jl - sf * itau_f
            Ad = epsVd - t0 * qd
            wk = wt[k]
            wdu2 = wk * dd[k] * iu * iu
            T += wdu2 * A * A
            I += wk * (Ad * iu + Jl) - wdu2 * A * v * D
            C += wk * iu
            U += wk * ((A * A + 2.0 * t0 * A * qs) * iu + t0 * qs * qs)
            Q += wk * sf
            # E_l t_l J_l = sigma_l (u - T0) J_l / eps_l; 2 t_f E_f J_f = (T0/eps_l) sigma_f^2 / tau_f
            PJ += wk * ieps_l * (sl * (u - t0) * Jl + t0 * sf * sf * itau_f)
            if pol:
                # the branch: its current dP/dt, energy t_l P^2/(2 chi eps_l) (in U's
                # units, times 2 eps_l) and loss t_l tau_p (dP/dt)^2/(chi eps_l); the
                # interface charge moves by g + dP/dt pointwise
                T += wk * dd[k] * Ps * Ps * ichi
                I += wk * Pd
                U += wk * (u - t0) * Ps * Ps * ichi
                Pd_pt = (mat[CHI_P] * sl - Ps) / mat[TAU_P]
                lossP = wk * ieps_l * (u - t0) * mat[TAU_P] * ichi
                PJ += lossP * Pd_pt * Pd_pt
                Pint += wk * t0 * ieps_l * sf * (g + Pd - qd) + lossP * Pd_pt * (Pd - Pd_pt)
            else:
                Pint += wk * t0 * ieps_l * sf * (g - qd)
            Emax = max(Emax, abs(sl))
    Emax *= ieps_l
    # the series resistance's loss is the source's: R_s I^2
    Psrc = mat[R_S] * (w * I) ** 2 if rs else 0.0
    write_outputs(layout, geo, mat, kin, y, v, V, F, D * T, w * I, w * eps_l * C, w / (2.0 * eps_l) * U, w * Q,
                  Emax, w * PJ, w * Pint, Psrc, rec, P)
