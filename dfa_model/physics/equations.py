"""Assembled state equations (compiled): element integrals, right-hand side, Jacobian,
and output diagnostics, for both numerical schemes.

State vector y = [x, (v if m > 0), element states]. Elements are the N - 1 material
portions of length ds = l_e/(N - 1).

scheme 0, "continuum" (default; see README and ../shared/notes/numerics.md):
    one state per element, the interface charge q = sigma_f - sigma_l, uniform on the
    element. Pointwise sigma_l(s) = A/u(s) with A = eps_l V - T0 q, T0 = 2 eps_l t_f/eps_f,
    u = t_l + T0; the element integrals of 1/u, 1/u^2, (dt_l/dp)/u^2 and of the
    leakage current are done exactly (closed form for the v-shaped gap, graded
    Gauss-Legendre otherwise), so force and charge rates are continuous in x.
scheme 1, "paper": Eq. (9) midpoint force and the pseudo-transient Eq. (15): two
    states (sigma_l, sigma_f) per element and a fictitious series resistance rho_t_s.

`mat` packs material and mechanical constants (indices below); `cfg` the integer
switches [layout, scheme, law_is_constant, nb, nbord, M, polarization, series resistance].
"""
from __future__ import annotations

import math

import numpy as np
from .._jit import njit

from .kinematics import V_SHAPED, front_slope, kin_eval, profile, zipping_angle

# mat indices
EPS_L, EPS_F, T_F, T_LZ, T0, U0, TAU_L, TAU_F, RHO_TS, B, MASS, K, DS, W, XSC, QSC, X_E, CHI_P, TAU_P, R_S = range(20)
NMAT = 20  # XSC, QSC: stroke and charge-density scales for tolerances and differences; X_E: the upper stop;
# CHI_P, TAU_P: the liquid's fast (Debye) relaxation; R_S: the series resistance (nodal scheme only)
# cfg indices
C_LAYOUT, C_SCHEME, C_CONST, C_NB, C_NBORD, C_M, C_POL, C_RS = range(8)
# output record columns
(R_T, R_X, R_V, R_LZ, R_ANG, R_FE, R_I, R_C, R_U, R_VOLT, R_F, R_EMAX, R_Q,
 R_EIN, R_EJ, R_EINTRA, R_ESRC, R_EDAMP, R_ELOAD, R_EIMPACT) = range(20)
NREC = 20
NPOW = 7  # P_in, P_joule, P_intra, P_source, P_damp, P_load, impacts (booked per event, no power)

_GX, _GW = np.polynomial.legendre.leggauss(8)
GX = np.ascontiguousarray(_GX)
GW = np.ascontiguousarray(_GW)


@njit(cache=True, _nrt=False)
def rho_and_slope(law, lawp, E_abs):
    """(rho, g): the liquid resistivity for |E_l| under law id `law` (see dielectrics) and
    its log-log slope g = d ln rho/d ln |E| (on the side of a law's kink the field is on).
    The one place the laws are written: rho_of keeps rho, j_and_slope both."""
    g = 0.0
    if law == 0:
        rho = lawp[0]
    elif law == 1:
        rho = lawp[0] * E_abs + lawp[1]
        if rho > lawp[2]:
            g = lawp[0] * E_abs / rho
        else:
            rho = lawp[2]
    else:
        # 2: table, log rho linear in log E on a uniform grid; held constant outside
        n = int(lawp[0])
        pos = (math.log(max(E_abs, 1e-300)) - lawp[1]) / lawp[2]
        if pos <= 0.0:
            rho = math.exp(lawp[3])
        elif pos >= n - 1:
            rho = math.exp(lawp[3 + n - 1])
        elif pos != pos:    # a NaN field (a non-finite state): NaN, not int(NaN) = -2^63 as an index
            rho = g = pos
        else:
            i = int(pos)
            fr = pos - i
            rho = math.exp(lawp[3 + i] * (1.0 - fr) + lawp[4 + i] * fr)
            g = (lawp[4 + i] - lawp[3 + i]) / lawp[2]
    return rho, g


@njit(cache=True, _nrt=False)
def rho_of(law, lawp, E_abs):
    """Liquid resistivity for |E_l| under law id `law` (see dielectrics)."""
    return rho_and_slope(law, lawp, E_abs)[0]


@njit(cache=True, _nrt=False)
def j_of_E(law, lawp, E):
    """Leakage current density in the liquid for field E (A/m^2)."""
    return E / rho_of(law, lawp, abs(E))


@njit(cache=True, _nrt=False, inline="always")
def j_and_slope(law, lawp, E, eps_l):
    """(J_l(E), dJ_l/dsigma_l): the leakage current density and its slope in the liquid
    charge sigma_l = eps_l E. The pointwise rate of the nodal scheme and of the surrogate's
    material points, evaluated at every quadrature node of every rhs call. Analytic: with
    J = E/rho(|E|), dJ/dE = (1 - g)/rho, g = d ln rho/d ln |E| (rho_and_slope). A central
    difference took three evaluations of the law, each a log and an exp for the table
    law: a run with the spline law cost 3.2x the constant law's at the same steps, now
    2.5x (Eq. (21)'s: 1.24x)."""
    rho, g = rho_and_slope(law, lawp, abs(E))
    return E / rho, (1.0 - g) / (rho * eps_l)


@njit(cache=True, _nrt=False)
def elem_moments(cfg, geo, mat, law, lawp, kin, sa, sb, A, out):
    """Integrals over element [sa, sb] (absolute s) into out:
    [m1 = int 1/u, m2 = int 1/u^2, fI = int (dt_l/dp)/u^2, Q0 = int J_l, Q1 = int J_l/u]."""
    layout = cfg[C_LAYOUT]
    const = cfg[C_CONST] == 1
    eps_l, u0 = mat[EPS_L], mat[U0]
    lz = kin[0]
    zl = min(sb, lz) - sa
    if zl < 0.0:
        zl = 0.0
    m1 = zl / u0
    m2 = zl / (u0 * u0)
    fI = 0.0
    Q0 = 0.0
    Q1 = 0.0
    if not const and zl > 0.0:
        J0 = j_of_E(law, lawp, A / (eps_l * u0))
        Q0 = zl * J0
        Q1 = zl * J0 / u0
    if sb > lz:
        sga = max(sa, lz) - lz
        sgb = sb - lz
        closed = layout == V_SHAPED
        if closed:
            k, rem = kin[2], kin[3]
            ua = u0 + k * sga
            du = k * (sgb - sga)
            ub = ua + du
            lnr = math.log1p(du / ua)
            inv = du / (ua * ub)
            m1 += lnr / k
            m2 += inv / k
            two_a = k * rem
            fI += -(1.0 + u0 / two_a) * inv + lnr / two_a
        if (not closed) or (not const):
            # graded Gauss: y = ln(sigma + c) makes the 1/u-like integrands smooth
            c = u0 / front_slope(layout, kin)
            ya = math.log(sga + c)
            yb = math.log(sgb + c)
            hy = 0.5 * (yb - ya)
            ym = 0.5 * (yb + ya)
            for i in range(GX.shape[0]):
                ey = math.exp(ym + hy * GX[i])
                sg = ey - c
                wt = hy * GW[i] * ey
                gap, dgap = profile(layout, geo, kin, sg)
                u = u0 + gap
                if not closed:
                    m1 += wt / u
                    m2 += wt / (u * u)
                    fI += wt * dgap / (u * u)
                if not const:
                    J = j_of_E(law, lawp, A / (eps_l * u))
                    Q0 += wt * J
                    Q1 += wt * J / u
    if const:
        Q0 = A * m1 / mat[TAU_L]
        Q1 = A * m2 / mat[TAU_L]
    out[0] = m1
    out[1] = m2
    out[2] = fI
    out[3] = Q0
    out[4] = Q1


@njit(cache=True, _nrt=False)
def elem_rate(cfg, geo, mat, law, lawp, kin, j, V, ye, r, mom):
    """Rates r[:nb] of element j with states ye[:nb]; returns its force term T_j
    (F_e = w/(2 eps_l) * D * sum_j T_j). mom receives the element moments."""
    ds = mat[DS]
    sa = j * ds
    sb = sa + ds
    if cfg[C_SCHEME] == 0:
        q = ye[0]
        A = mat[EPS_L] * V - mat[T0] * q
        elem_moments(cfg, geo, mat, law, lawp, kin, sa, sb, A, mom)
        r[0] = (mom[3] - (A * mom[0] + q * ds) / mat[TAU_F]) / ds
        return A * A * mom[2]
    # paper: midpoint thickness, pseudo-transient series resistor
    sl, sf = ye[0], ye[1]
    sig = sa + 0.5 * ds - kin[0]
    gap, dgap = 0.0, 0.0
    if sig > 0.0 and kin[0] < geo[2]:
        gap, dgap = profile(cfg[C_LAYOUT], geo, kin, sig)
    t_l = mat[T_LZ] + gap
    i = (V - sl * t_l / mat[EPS_L] - sf * 2.0 * mat[T_F] / mat[EPS_F]) / mat[RHO_TS]
    r[0] = i - j_of_E(law, lawp, sl / mat[EPS_L])
    r[1] = i - sf / mat[TAU_F]
    mom[0] = t_l
    mom[1] = i
    return ds * sl * sl * dgap


@njit(cache=True, _nrt=False)
def mech_rhs(cfg, mat, F, y, Fe, ydot):
    """Eq. (7): m x'' + b x' + k x + F + F_e = 0, free motion. The stroke's stops at
    x = 0 (films straight) and x = x_e (front at the electrode end) are events of the
    integrator, which holds the motion while the net force pushes into a stop: a clamp
    here would put a kink into the implicit stages (with mass, the step size collapsed
    on it)."""
    if cfg[C_NBORD] == 1:
        ydot[0] = -(F + mat[K] * y[0] + Fe) / mat[B]
    else:
        ydot[0] = y[1]
        ydot[1] = -(mat[B] * y[1] + F + mat[K] * y[0] + Fe) / mat[MASS]


@njit(cache=True, _nrt=False)
def stroke_velocity(cfg, mat, y, ydot):
    """dx/dt for the outputs: zero while resting on a stop."""
    v = ydot[0] if cfg[C_NBORD] == 1 else y[1]
    if (y[0] <= 0.0 and v < 0.0) or (y[0] >= mat[X_E] and v > 0.0):
        v = 0.0
    return v


@njit(cache=True, _nrt=False)
def rhs(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work):
    """ydot = f(y) at voltage V and load F. Returns F_e (N, negative = zipping)."""
    nb, nbord, M = cfg[C_NB], cfg[C_NBORD], cfg[C_M]
    kin_eval(cfg[C_LAYOUT], geo, y[0], kin)
    T = 0.0
    for j in range(M):
        o = nbord + j * nb
        T += elem_rate(cfg, geo, mat, law, lawp, kin, j, V, y[o:o + nb], ydot[o:o + nb], work)
    Fe = mat[W] / (2.0 * mat[EPS_L]) * kin[1] * T
    mech_rhs(cfg, mat, F, y, Fe, ydot)
    return Fe


@njit(cache=True, _nrt=False)
def jacobian(cfg, geo, mat, law, lawp, V, F, y, f0, Jee, Jeb, Jbe, Jbb, kin, work, tmp, ytmp):
    """Arrowhead Jacobian: element blocks Jee[j] (nb x nb), their x-column Jeb[j],
    the force row Jbe[j] (d of the force-bearing mechanical rate), and Jbb.
    f0 is scratch space (receives f(y))."""
    nb, nbord, M = cfg[C_NB], cfg[C_NBORD], cfg[C_M]
    cF = mat[W] / (2.0 * mat[EPS_L])
    fb = nbord - 1
    # differences need an exact base value (f0 from the integrator may be constrained
    # or carry Newton error, which 1/h would amplify)
    rhs(cfg, geo, mat, law, lawp, V, F, y, f0, kin, work)
    den = mat[B] if nbord == 1 else mat[MASS]
    kin_eval(cfg[C_LAYOUT], geo, y[0], kin)
    D = kin[1]
    rr = work[8:10]
    ye = work[10:12]
    analytic = cfg[C_SCHEME] == 0 and cfg[C_CONST] == 1
    for j in range(M):
        o = nbord + j * nb
        if analytic:
            q = y[o]
            A = mat[EPS_L] * V - mat[T0] * q
            elem_moments(cfg, geo, mat, law, lawp, kin, j * mat[DS], (j + 1) * mat[DS], A, work)
            Jee[j, 0, 0] = (-mat[T0] * work[0] / mat[TAU_L] + mat[T0] * work[0] / mat[TAU_F]
                            - mat[DS] / mat[TAU_F]) / mat[DS]
            Jbe[j, 0] = -cF * D * (-2.0 * mat[T0] * A * work[2]) / den
            continue
        for c in range(nb):
            ye[c] = y[o + c]
        T_base = elem_rate(cfg, geo, mat, law, lawp, kin, j, V, ye, rr, work[0:8])
        for c in range(nb):
            h = 1e-7 * max(abs(ye[c]), mat[QSC])
            ye[c] += h
            Tp = elem_rate(cfg, geo, mat, law, lawp, kin, j, V, ye, tmp, work[0:8])
            ye[c] -= h
            for rrow in range(nb):
                Jee[j, rrow, c] = (tmp[rrow] - f0[o + rrow]) / h
            Jbe[j, c] = -cF * D * (Tp - T_base) / h / den
    # x column by a forward difference of the whole right-hand side
    hx = 1e-7 * mat[XSC]
    if y[0] + hx > mat[X_E]:      # at the upper stop: difference towards the interior
        hx = -hx
    for i in range(y.shape[0]):
        ytmp[i] = y[i]
    ytmp[0] += hx
    rhs(cfg, geo, mat, law, lawp, V, F, ytmp, tmp, kin, work)
    for j in range(M):
        o = nbord + j * nb
        for rrow in range(nb):
            Jeb[j, rrow] = (tmp[o + rrow] - f0[o + rrow]) / hx
    mech_jacobian(cfg, mat, tmp, f0, hx, Jbb)
    kin_eval(cfg[C_LAYOUT], geo, y[0], kin)
    return fb


@njit(cache=True, _nrt=False)
def mech_jacobian(cfg, mat, fx, f0, hx, Jbb):
    """Mechanical block of the Jacobian from f(x + hx) = fx and f(x) = f0."""
    Jbb[:, :] = 0.0
    if cfg[C_NBORD] == 1:
        Jbb[0, 0] = (fx[0] - f0[0]) / hx
    else:
        Jbb[0, 1] = 1.0
        Jbb[1, 0] = (fx[1] - f0[1]) / hx
        Jbb[1, 1] = -mat[B] / mat[MASS]


@njit(cache=True, _nrt=False)
def factor(cfg, gh, Jee, Jeb, Jbe, Jbb, fb, Winv, zeta, S):
    """Factor W = I - gh J: per-element inverses Winv, zeta = Wee^-1 Web, Schur S."""
    nb, nbord, M = cfg[C_NB], cfg[C_NBORD], cfg[C_M]
    for a in range(nbord):
        for b in range(nbord):
            S[a, b] = (1.0 if a == b else 0.0) - gh * Jbb[a, b]
    for j in range(M):
        if nb == 1:
            Winv[j, 0, 0] = 1.0 / (1.0 - gh * Jee[j, 0, 0])
            zeta[j, 0] = Winv[j, 0, 0] * (-gh * Jeb[j, 0])
            S[fb, 0] -= (-gh * Jbe[j, 0]) * zeta[j, 0]
        else:
            a11 = 1.0 - gh * Jee[j, 0, 0]
            a12 = -gh * Jee[j, 0, 1]
            a21 = -gh * Jee[j, 1, 0]
            a22 = 1.0 - gh * Jee[j, 1, 1]
            det = a11 * a22 - a12 * a21
            Winv[j, 0, 0] = a22 / det
            Winv[j, 0, 1] = -a12 / det
            Winv[j, 1, 0] = -a21 / det
            Winv[j, 1, 1] = a11 / det
            for c in range(2):
                zeta[j, c] = -gh * (Winv[j, c, 0] * Jeb[j, 0] + Winv[j, c, 1] * Jeb[j, 1])
            S[fb, 0] -= -gh * (Jbe[j, 0] * zeta[j, 0] + Jbe[j, 1] * zeta[j, 1])


@njit(cache=True, _nrt=False)
def solve(cfg, gh, Winv, zeta, Jbe, S, fb, r, out):
    """out = W^-1 r using the factorization (O(M))."""
    nb, nbord, M = cfg[C_NB], cfg[C_NBORD], cfg[C_M]
    rb0 = r[0]
    rb1 = r[1] if nbord == 2 else 0.0
    acc = 0.0
    for j in range(M):
        o = nbord + j * nb
        if nb == 1:
            z = Winv[j, 0, 0] * r[o]
            out[o] = z
            acc += -gh * Jbe[j, 0] * z
        else:
            z0 = Winv[j, 0, 0] * r[o] + Winv[j, 0, 1] * r[o + 1]
            z1 = Winv[j, 1, 0] * r[o] + Winv[j, 1, 1] * r[o + 1]
            out[o] = z0
            out[o + 1] = z1
            acc += -gh * (Jbe[j, 0] * z0 + Jbe[j, 1] * z1)
    if nbord == 1:
        rb0 -= acc
        dx = rb0 / S[0, 0]
        out[0] = dx
    else:
        rb1 -= acc
        det = S[0, 0] * S[1, 1] - S[0, 1] * S[1, 0]
        dx = (rb0 * S[1, 1] - S[0, 1] * rb1) / det
        dv = (S[0, 0] * rb1 - S[1, 0] * rb0) / det
        out[0] = dx
        out[1] = dv
    for j in range(M):
        o = nbord + j * nb
        for c in range(nb):
            out[o + c] -= zeta[j, c] * dx


@njit(cache=True, _nrt=False)
def diagnostics(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, rec, P):
    """Derived outputs at one state into rec (columns R_LZ..R_Q, R_V, R_VOLT, R_F) and
    powers P = [V I, Joule (both layers), intra-element redistribution, source
    (fictitious series resistor), damping b v^2, load (F + k x) v]."""
    nb, nbord, M = cfg[C_NB], cfg[C_NBORD], cfg[C_M]
    layout = cfg[C_LAYOUT]
    eps_l, T0v, u0, ds, w = mat[EPS_L], mat[T0], mat[U0], mat[DS], mat[W]
    kin_eval(layout, geo, y[0], kin)
    D = kin[1]
    v = stroke_velocity(cfg, mat, y, ydot)
    I = 0.0
    C = 0.0
    U = 0.0
    Q = 0.0
    PJ = 0.0
    Pint = 0.0
    Psrc = 0.0
    T = 0.0
    Emax = 0.0
    tau_f = mat[TAU_F]
    for j in range(M):
        o = nbord + j * nb
        if cfg[C_SCHEME] == 0:
            q = y[o]
            qd = ydot[o]
            A = eps_l * V - T0v * q
            elem_moments(cfg, geo, mat, law, lawp, kin, j * ds, (j + 1) * ds, A, work)
            m1, m2, fI, Q0, Q1 = work[0], work[1], work[2], work[3], work[4]
            Ad = eps_l * dVdt - T0v * qd
            T += A * A * fI
            I += Ad * m1 - A * v * D * fI + Q0
            C += m1
            U += (A * A + 2.0 * T0v * A * q) * m1 + T0v * q * q * ds
            Q += A * m1 + q * ds
            S1 = A * m1 + q * ds                      # int sigma_f
            S2 = A * A * m2 + 2.0 * A * q * m1 + q * q * ds   # int sigma_f^2
            PJ += (A / eps_l) * (Q0 - T0v * Q1) + T0v / eps_l * S2 / tau_f
            g = Q0 - S1 / tau_f                       # int (J_l - J_f)
            sfg = A * Q1 + q * Q0 - S2 / tau_f        # int sigma_f (J_l - J_f)
            Pint += T0v / eps_l * (sfg - S1 * g / ds)  # >= 0, vanishes as ds -> 0
            sg = j * ds - kin[0]   # the largest field of the element is at its end nearest the front
            umin = u0 + (profile(layout, geo, kin, sg)[0] if sg > 0.0 and kin[0] < geo[2] else 0.0)
            Emax = max(Emax, abs(A) / (eps_l * umin))
        else:
            sl, sf = y[o], y[o + 1]
            T += elem_rate(cfg, geo, mat, law, lawp, kin, j, V, y[o:o + 2], work[5:7], work)
            t_l, i = work[0], work[1]
            I += ds * i
            C += ds / (t_l + T0v)
            U += ds * (sl * sl * t_l / eps_l + T0v / eps_l * sf * sf)
            Q += ds * sf
            Jl = j_of_E(law, lawp, sl / eps_l)
            PJ += ds * (t_l * sl / eps_l * Jl + T0v / eps_l * sf * sf / tau_f)
            Psrc += ds * mat[RHO_TS] * i * i
            Emax = max(Emax, abs(sl) / eps_l)
    # U was summed without its prefactor: w/(2 eps_l) (continuum-p0) or w/2 (paper)
    U_scale = w / (2.0 * eps_l) if cfg[C_SCHEME] == 0 else 0.5 * w
    write_outputs(layout, geo, mat, kin, y, v, V, F, D * T, w * I, w * eps_l * C, U_scale * U, w * Q, Emax,
                  w * PJ, w * Pint, w * Psrc, rec, P)


@njit(cache=True, _nrt=False)
def write_outputs(layout, geo, mat, kin, y, v, V, F, T, I, C, U, Q, Emax, PJ, Pint, Psrc, rec, P):
    """Fill the output record and the powers from the (scaled) element sums; T is the
    force sum times the lever D."""
    Fe = mat[W] / (2.0 * mat[EPS_L]) * T
    rec[R_V] = v
    rec[R_LZ] = kin[0]
    rec[R_ANG] = zipping_angle(layout, geo, kin)
    rec[R_FE] = -Fe
    rec[R_I] = I
    rec[R_C] = C
    rec[R_U] = U
    rec[R_VOLT] = V
    rec[R_F] = F
    rec[R_EMAX] = Emax
    rec[R_Q] = Q
    P[0] = V * I
    P[1] = PJ
    P[2] = Pint
    P[3] = Psrc
    P[4] = mat[B] * v * v
    P[5] = (F + mat[K] * y[0]) * v
    P[6] = 0.0
