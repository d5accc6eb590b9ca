"""The full model at frozen strokes: its electrical subsystem and its static maps.

At a fixed stroke x and a constant resistivity law, the full model's interface-charge
equations are linear in (q, V) and its electrostatic force is a quadratic form in (V, q).
Everything here is read off the full model (`DFAModel.rhs`, `.electrostatic_force`,
`.diagnostics`) by evaluating it at chosen states - never from a copy of its equations -
so a surrogate follows whatever physics the model carries.
"""
from __future__ import annotations

import math

import numpy as np

from dfa_model import DFAModel, Parameters
from dfa_model.numerics import surrogate_kernel as sk
from dfa_model.physics.equations import R_C, R_I, U0
from dfa_model.physics.equations import T0 as T0_INDEX


V_REF = 1000.0     # V: evaluation amplitude (the maps are exact quadratic/affine forms)
N_FRONT = 41       # grid points of the front layer's rates (about 25 ms each)
W_F_MIN = 0.5      # the front layer's least width, in u0


def as_model(params) -> DFAModel:
    """The full model of `params` (any physics the continuum scheme carries: laws, the
    polarization branch, a series resistance, mass, stiffness)."""
    if isinstance(params, DFAModel):
        model = params
    elif isinstance(params, Parameters):
        model = DFAModel(params)
    else:
        raise TypeError("expected Parameters or DFAModel")
    if model.params.scheme == "paper":
        raise ValueError("scheme: the surrogates are fitted to the 'continuum' or 'continuum-p0' schemes, "
                         "not 'paper' (its fictitious series resistor has no reduced form)")
    return model


E_REF = 5e7     # V/m: the field at which a field-dependent law's resistivity sets the plain twin's


def plain(model: DFAModel) -> DFAModel:
    """The actuator without the physics that only the pointwise rates carry (the
    polarization branch, a series resistance, a field-dependent law: its resistivity at
    E_REF, the zipped field of about 5 kV): its frozen-stroke maps are linear in (V, q),
    and the front layer's effective point (front_point), the force's and the current's
    maps are read off it. The effective point does not depend on the resistivity (the
    layer's gap and screening thickness: within 0.1 um and 3 % over a 16x range of rho_l,
    README 'Surrogates'), so the law's own conductance applies to it in the kernel."""
    p = model.params
    changes = {}
    if p.chi_p > 0:
        changes["chi_p"] = 0.0
    if p.R_s > 0:
        changes["R_s"] = 0.0
    if not model.law.is_constant:
        changes.update(law="constant", rho_l=float(model.law.rho(np.array([E_REF]))[0]))
    return DFAModel(p.replace(**changes)) if changes else model


def u0(model: DFAModel) -> float:
    """The zipped liquid's effective thickness t_lz + 2 eps_l t_f / eps_f (m)."""
    return float(model.mat[U0])


def q_scale(model: DFAModel) -> float:
    """Interface-charge scale (C/m^2): the zipped liquid's surface charge at 1 kV."""
    return float(model.scales(V_REF)[model.nbord])


def state(model: DFAModel, x: float, q=None, v: float = 0.0) -> np.ndarray:
    y = model.initial_state(x)
    if model.nbord == 2:
        y[1] = v
    if q is not None:
        y[model.nbord:] = q
    return y


def electrical_lti(model: DFAModel, x: float):
    """(A, B) of dq/dt = A q + B V at frozen stroke x (q: the model's element states)."""
    nb, n = model.nbord, model.n_states
    qs = q_scale(model)
    y = state(model, x)
    f0 = model.rhs(y, 0.0, 0.0)[nb:]
    A = np.empty((n, n))
    for j in range(n):
        yy = y.copy()
        yy[nb + j] = qs
        A[:, j] = (model.rhs(yy, 0.0, 0.0)[nb:] - f0) / qs
    B = (model.rhs(y, V_REF, 0.0)[nb:] - f0) / V_REF
    return A, B


def force_sensitivity(model: DFAModel, x: float) -> np.ndarray:
    """dF_e/dq_j per volt at q = 0 (the force's bilinear V q term): where along the
    electrode the interface charge acts on the force."""
    n = model.n_states
    qs = q_scale(model)
    Fv = model.electrostatic_force(state(model, x), V_REF)
    h = np.empty(n)
    for j in range(n):
        q = np.zeros(n)
        q[j] = qs
        y = state(model, x, q)
        h[j] = (model.electrostatic_force(y, V_REF) - Fv - model.electrostatic_force(y, 0.0)) / (qs * V_REF)
    return h


def zipped_rates(model: DFAModel):
    """(a, b) of dq/dt = a q + b V for zipped material: every fully zipped element has
    the same dynamics, read at the middle of an all-zipped electrode (x = x_e)."""
    nb, n = model.nbord, model.n_states
    qs = q_scale(model)
    x_e = model.kin.x_e
    j = nb + n // 2
    f0 = model.rhs(state(model, x_e), 0.0, 0.0)[j]
    a = (model.rhs(state(model, x_e, np.full(n, qs)), 0.0, 0.0)[j] - f0) / qs
    b = (model.rhs(state(model, x_e), V_REF, 0.0)[j] - f0) / V_REF
    return float(a), float(b)


def front_layer(model: DFAModel, x: float, zipped=None):
    """(a_f, b_f, w_f) of the front layer at stroke x.

    (a_f, b_f): the one-pole model b_f / (s - a_f) of the force-weighted charge
    h^T q / h^T 1 (h: force_sensitivity; zipped material has h = 0, the force acts
    through the material just beyond the front) whose Markov parameter (h^T B / h^T 1:
    the charging rate, which sets the ripple under fast inversion) and DC gain
    (-h^T A^-1 B / h^T 1: the steady charge) are the full model's (moment matching at
    s = infinity and s = 0).
    w_f: the layer's width, the force-weighted mean distance of that material beyond
    the front, sum h_j (s_j - l_z) / sum h_j (m). It sets how far the front must move to
    replace the layer with zipped material; it shrinks from 5-8 u0 with the front near the hinge
    to nothing at the electrode end, as the gap opens ever faster beyond the front.
    Where no material is at the front (h = 0), zipped rates (`zipped`: zipped_rates(model),
    if the caller has them) and w_f = NaN."""
    A, B = electrical_lti(model, x)
    h = force_sensitivity(model, x)
    H = h.sum()
    a, b = zipped if zipped is not None else zipped_rates(model)
    if not abs(H) > 1e-9 * np.abs(h).sum() or not np.isfinite(H):
        return a, b, float("nan")
    s = model.element_edges()[: len(h)]      # the charge states sit at the element edges
    w_f = float(h @ (s - float(model.kin.lz(x)))) / H
    m0 = float(h @ B) / H
    g0 = float(h @ np.linalg.solve(A, -B)) / H
    if not (m0 * b > 0 and g0 * b > 0):     # a front that does not charge like a layer
        return a, b, w_f
    return -m0 / g0, m0, w_f


def _current(model: DFAModel, x, V, q, xdot):
    """Device current at stroke x, voltage V, uniform charge q and stroke velocity xdot:
    the load is chosen so the mechanics give that velocity."""
    p = model.params
    y = state(model, x, q, xdot)
    Fe = model.electrostatic_force(y, V)
    F = Fe - p.k * x - p.b * xdot     # with a mass the velocity is the state y[1]; F then only sets dv/dt
    return model.diagnostics(y, V, F)[0][R_I]


# ------------------------------------------------------------------ material-point surrogate
def _uniform(model: DFAModel, x: float, q: float = 0.0, P: float = 0.0, v: float = 0.0) -> np.ndarray:
    """State at stroke x with a uniform interface charge q (the q' the electrostatics
    see) and, with the polarization branch, a uniform polarization P."""
    y = model.initial_state(x)
    if model.nbord == 2:
        y[1] = v
    nq = model.params.N
    y[model.nbord:model.nbord + nq] = q
    if model.polarized:
        y[model.nbord + nq:model.nbord + 2 * nq] = P
    return y


def front_point(plain_model: DFAModel, a_f: float, b_f: float) -> tuple[float, float]:
    """(1/u_f, T0_f): the effective material point whose pointwise rates
    dq/dt = c (eps_l V - T0_f q) / u_f - q / tau_f are the front layer's (a_f, b_f),
    c = 1/tau_l - 1/tau_f. Matched dielectrics (c = 0) have no layer dynamics to match:
    the zipped material's point."""
    p = plain_model.params
    c = 1.0 / (p.rho_l * p.eps_l) - 1.0 / p.tau_f
    u0_ = u0(plain_model)
    T0 = 2.0 * p.eps_l * p.t_f / p.eps_f
    if not abs(c) > 1e-9 / p.tau_f or not np.isfinite(a_f * b_f):
        return 1.0 / u0_, T0
    iu = b_f / (c * p.eps_l)
    t0f = -(a_f + 1.0 / p.tau_f) / (c * iu) if iu != 0 else T0
    if not (iu > 0 and np.isfinite(t0f) and t0f > 0):
        return 1.0 / u0_, T0
    return float(iu), float(t0f)


def point_positions(model: DFAModel, n_points: int) -> np.ndarray:
    """The material points' positions along the electrode (both ends included)."""
    return np.linspace(0.0, model.params.l_e, n_points) if n_points >= 2 else np.zeros(0)


def wake_gap(model: DFAModel, xg, w_f, c_w: float) -> np.ndarray:
    """The unzipped wake's mean inverse gap over [l_z, l_z + c_w w_f] at each stroke
    (clipped at the electrode's end; the zipped gap where nothing is left)."""
    gx, gw = np.polynomial.legendre.leggauss(10)
    T0 = 2.0 * model.params.eps_l * model.params.t_f / model.params.eps_f
    out = np.empty(len(xg))
    for i, x in enumerate(xg):
        lz = float(model.kin.lz(x))
        L = min(c_w * w_f[i], model.params.l_e - lz)
        if not L > 0:
            out[i] = 1.0 / u0(model)
            continue
        s_ = lz + 0.5 * L * (1.0 + gx)
        out[i] = float(np.sum(0.5 * gw / (model.kin.t_l(s_, x) + T0)))
    return out


def material_tables(model: DFAModel, n_grid: int = 161, n_points: int = 11, c_w: float = 2.0):
    """(x_grid, tables) of the material-point surrogate (dfa_model.numerics.surrogate_kernel's
    columns): over x in [0, x_e] the force's quadratic map in the layer's (V, q, P), the
    layer's effective point, width and the front's lever, the device capacitance, the
    current's maps, the unzipped wake's mean gap (c_w layer widths wide) and each
    material point's inverse gap 1/u(s_i, x)."""
    pm = plain(model)
    x_e = model.kin.x_e
    xg = np.linspace(0.0, x_e, n_grid)
    qs = q_scale(pm)
    tab = np.zeros((n_grid, sk.NFIX + n_points))
    # the front layer: its rates, effective point and width (a coarser grid: each point
    # solves the charge system)
    a, b = zipped_rates(pm)
    xf = np.linspace(0.0, x_e, N_FRONT)
    af, bf, wf = np.array([front_layer(pm, x, (a, b)) for x in xf]).T
    pts = np.array([front_point(pm, fa, fb) for fa, fb in zip(af, bf)])
    tab[:, sk.IUF], tab[:, sk.T0F] = np.interp(xg, xf, pts[:, 0]), np.interp(xg, xf, pts[:, 1])
    ok = np.isfinite(wf) & (wf > 0)
    wf = np.interp(xf, xf[ok], wf[ok]) if ok.any() else np.ones_like(xf)
    tab[:, sk.WF] = np.maximum(np.interp(xg, xf, wf), W_F_MIN * u0(pm))
    T0 = float(pm.mat[T0_INDEX])
    dv = 1e-3 * x_e
    for i, x in enumerate(xg):
        fv = pm.electrostatic_force(_uniform(pm, x), V_REF)
        fq = pm.electrostatic_force(_uniform(pm, x, qs), 0.0)
        fvq = pm.electrostatic_force(_uniform(pm, x, qs), V_REF)
        tab[i, sk.C0] = fv / V_REF ** 2
        tab[i, sk.C2] = fq / qs ** 2
        tab[i, sk.C1] = (fvq - fv - fq) / (V_REF * qs)
        iv = _current(pm, x, V_REF, None, 0.0)
        iq = _current(pm, x, 0.0, np.full(pm.n_states, qs), 0.0)
        tab[i, sk.I0], tab[i, sk.I1] = iv / V_REF, iq / qs
        tab[i, sk.J0] = (_current(pm, x, V_REF, None, dv) - iv) / (dv * V_REF)
        tab[i, sk.J1] = (_current(pm, x, 0.0, np.full(pm.n_states, qs), dv) - iq) / (dv * qs)
        tab[i, sk.CAP] = pm.diagnostics(state(pm, x), V_REF)[0][R_C]
    tab[:, sk.DLZ] = pm.kin.dlz_dx(xg)
    tab[:, sk.LZ] = pm.kin.lz(xg)
    s_pts = point_positions(pm, n_points)
    for i, x in enumerate(xg):
        tab[i, sk.NFIX:] = 1.0 / (pm.kin.t_l(s_pts, x) + T0)
    tab[:, sk.IUA] = wake_gap(pm, xg, tab[:, sk.WF], c_w)
    if model.polarized:
        tab[:, sk.PAA], D, O = polarization_weights(model, xg, tab[:, sk.WF] * c_w, tab[:, sk.IUA], s_pts)
        tab = np.hstack([tab, D, O])
    return xg, tab


def polarization_weights(model: DFAModel, xg, L_a, iu_a, s_pts):
    """The polarization's force, a quadratic form in the ahead wake's P_a and the
    material points' P_i: (W_aa, D, O) at each stroke, F_P = W_aa P_a^2 + sum_i D_i P_i^2
    + 2 sum_i O_i P_i P_{i+1}.

    The branch's energy t_l P^2/(2 chi_p eps_l) gives a force c dt_l/dx P^2 over the
    whole unzipped length (c read off the full model with a uniform P at each stroke),
    not through the front alone as the field's does: released at zero voltage, a front
    that retreats over material zipped a moment ago is held by that material's P,
    millimetres of it. So the profile P(s) is rebuilt from the states that carry it:
    over the ahead wake's band [l_z, l_z + L_a] P_a shaped as 1/u (the field's profile
    there, P_a its band mean: the wake's rates see the band's mean inverse gap), beyond
    it P u linear between the material points, which is exact both for a P that follows
    the field (P u constant) and for material carrying one zipped P (u linear in s)."""
    p = model.params
    N, nb = p.N, model.nbord
    T0 = 2.0 * p.eps_l * p.t_f / p.eps_f
    n = len(s_pts)
    W_aa = np.zeros(len(xg))
    D = np.zeros((len(xg), n))
    O = np.zeros((len(xg), n))
    r = np.unique(np.r_[np.geomspace(1e-7, 1.0, 1200), np.linspace(0.0, 1.0, 801)])
    for k, x in enumerate(xg):
        lz = float(model.kin.lz(x))
        if lz >= p.l_e:
            continue
        y = model.initial_state(x)
        y[nb + N:nb + 2 * N] = 1.0
        s = lz + (p.l_e - lz) * r
        G = model.kin.dt_l_dx(s, x)
        norm = np.trapezoid(G, s)
        if not abs(norm) > 0:
            continue
        c = model.electrostatic_force(y, 0.0) / norm        # the force of a uniform unit P
        sa = min(lz + L_a[k], p.l_e)
        s = np.unique(np.r_[s, sa, s_pts[(s_pts > lz) & (s_pts < p.l_e)]])
        G = c * model.kin.dt_l_dx(s, x)
        u = model.kin.t_l(s, x) + T0
        band = s <= sa
        if band.sum() > 1:
            W_aa[k] = np.trapezoid((G / (u * iu_a[k]) ** 2)[band], s[band])
        sl, Gl, ul = s[~band | (s == sa)], G[~band | (s == sa)], u[~band | (s == sa)]
        if len(sl) < 2:
            continue
        u_pts = model.kin.t_l(s_pts, x) + T0
        # each trapezoid piece [sl_j, sl_j+1] lies in one interval i (the points are grid
        # nodes): both its ends weighed with that interval's pair
        i = np.clip(np.searchsorted(s_pts, sl[:-1], side="right") - 1, 0, n - 2)
        h = s_pts[i + 1] - s_pts[i]
        ds = np.diff(sl)
        for end in (0, 1):
            se, ge, ue = sl[end:len(sl) - 1 + end], Gl[end:len(Gl) - 1 + end], ul[end:len(ul) - 1 + end]
            f = (se - s_pts[i]) / h
            # P(s) = (a_i (1 - f) + a_{i+1} f) / u(s), a_i = P_i u(s_i)
            w0 = (1.0 - f) * u_pts[i] / ue
            w1 = f * u_pts[i + 1] / ue
            np.add.at(D[k], i, 0.5 * ds * ge * w0 * w0)
            np.add.at(D[k], i + 1, 0.5 * ds * ge * w1 * w1)
            np.add.at(O[k], i, 0.5 * ds * ge * w0 * w1)
    return W_aa, D, O


# ------------------------------------------------------------------ the lattice form
def _geometric_twin(pm: DFAModel) -> DFAModel:
    """The plain model with a liquid resistivity that makes the points' charging rate
    c = 1/tau_l - 1/tau_f = 1/tau_f: the node rates c eps_l <1/u>_i V then give the
    hat-weighted inverse gaps <1/u>_i, which are geometry (any resistivity has the same)."""
    p = pm.params
    return DFAModel(p.replace(rho_l=0.5 * p.tau_f / p.eps_l))


LATTICE_GRID_PER_NODE = 4   # stroke grid points per node spacing the front crosses (lattice_grid)
LATTICE_N_MAX = 201         # the lattice family's largest N (a state per node; tables ~ N^2)
N_CURRENT = 161             # the current's weights: probed on this coarser grid, interpolated


def lattice_grid(model: DFAModel) -> int:
    """The lattice form's stroke grid: LATTICE_GRID_PER_NODE points per node spacing the
    front crosses. A node's force weights kink where the front crosses its hat, and a
    grid of one point per spacing (161 on a random Peano-HASEL at N = 161) put a
    telegraph's drift at 5.8 um against the full model's 8.0 (321 points: 8.1, 641: 7.9)."""
    p = model.params
    lz_max = float(model.kin.lz(model.kin.x_e))
    return max(161, int(math.ceil(LATTICE_GRID_PER_NODE * (p.N - 1) * min(lz_max / p.l_e, 1.0))) + 1)


def _profile_on(model: DFAModel, x: float, s: np.ndarray):
    """(u, dt_l/dx) at the unzipped positions s (> l_z) at stroke x: one profile call per
    point (kinematics.profile, the full model's own)."""
    from dfa_model.physics.kinematics import profile
    kin = model.kin.state(x)
    lay, geo = model.kin.layout_id, model.kin.geo
    T0 = float(model.mat[T0_INDEX])
    gap = np.empty(len(s))
    dgap = np.empty(len(s))
    for k, v in enumerate(s - kin[0]):
        gap[k], dgap[k] = profile(lay, geo, kin, float(v)) if v > 0 else (0.0, 0.0)
    return model.params.t_lz + gap + T0, dgap * kin[1]


_GRADED = np.unique(np.r_[np.geomspace(1e-8, 1.0, 900), np.linspace(0.0, 1.0, 401)])


def _unzipped_positions(lz: float, l_e: float, s_pts: np.ndarray) -> np.ndarray:
    """Quadrature positions over the unzipped length [l_z, l_e], graded towards the front
    (where the integrands 1/u^2 peak), holding every node there (hat_integrals)."""
    return np.unique(np.r_[lz + (l_e - lz) * _GRADED, s_pts[s_pts > lz]])


def hat_integrals(s_pts: np.ndarray, s: np.ndarray, g: np.ndarray):
    """(I1, I2, I2o): the integrals over the sampled positions s (trapezoid; s sorted and
    holding every node inside its span, so each piece lies in one element) of g phi_i,
    g phi_i^2 and g phi_i phi_(i+1), phi_i the nodes' hat functions."""
    n = len(s_pts)
    I1, I2, I2o = np.zeros(n), np.zeros(n), np.zeros(n)
    if len(s) < 2:
        return I1, I2, I2o
    j = np.clip(np.searchsorted(s_pts, 0.5 * (s[1:] + s[:-1]), side="right") - 1, 0, n - 2)
    h = s_pts[j + 1] - s_pts[j]
    ds = np.diff(s)
    for end in (0, 1):
        se, ge = s[end:len(s) - 1 + end], g[end:len(g) - 1 + end]
        f = np.clip((se - s_pts[j]) / h, 0.0, 1.0)
        w = 0.5 * ds * ge
        np.add.at(I1, j, w * (1.0 - f))
        np.add.at(I1, j + 1, w * f)
        np.add.at(I2, j, w * (1.0 - f) ** 2)
        np.add.at(I2, j + 1, w * f * f)
        np.add.at(I2o, j, w * f * (1.0 - f))
    return I1, I2, I2o


def lattice_tables(model: DFAModel, n_grid: int | None = None):
    """(x_grid, tables) of the lattice form (surrogate_kernel's columns, module
    docstring there): a material point at every node of the full model's lattice, each
    with the full model's pointwise physics at its hat-weighted inverse gap <1/u>_i (the
    nodal scheme's rates with the Galerkin coupling lumped: row sums, read off its rhs),
    the force's quadratic map in (V, q_i, P_i) and the source current's affine map in
    (V, q_i, dx/dt).

    The force is F = K int (eps_l V - T0 q(s))^2 (dt_l/dx) / u^2 ds over the unzipped
    length with q(s) linear between the nodes: its node weights are integrals of the hat
    functions against (dt_l/dx) / u^2 (hat_integrals on a grid graded towards the front),
    scaled by K from the full model's own force at each stroke; likewise the branch's
    P^2 force against dt_l/dx. The current's weights are probed (a node at a time) on a
    coarser grid (N_CURRENT) and interpolated: they only enter the current and V_d."""
    if model.params.scheme != "continuum":
        raise ValueError(f"scheme: the lattice family reads the nodes of the 'continuum' scheme, got "
                         f"{model.params.scheme!r} (use the charge family, or scheme = 'continuum')")
    N = model.params.N
    if N > LATTICE_N_MAX:
        size = (LATTICE_GRID_PER_NODE * (N - 1) + 1) * (sk.NFIX + (3 + sk.NLAT) * N)
        raise ValueError(f"N: the lattice family carries a state per node: N = {N} would be {N} states (twice "
                         f"that with the branch) and tables of up to {size / 1e6:.1f} million numbers; allowed "
                         f"N <= {LATTICE_N_MAX} (set N, or use the charge family)")
    pm = plain(model)
    p = pm.params
    N, nb = p.N, pm.nbord
    x_e = model.kin.x_e
    n_grid = lattice_grid(pm) if n_grid is None else int(n_grid)
    xg = np.linspace(0.0, x_e, n_grid)
    qs = q_scale(pm)
    s_pts = pm.element_edges()
    n = N
    tab = np.zeros((n_grid, sk.NFIX + 3 * n + sk.NLAT * n))
    o = sk.NFIX + 3 * n
    C1, C2, C2O, IQ, JQ = (o + k * n for k in range(sk.NLAT))
    geo = _geometric_twin(pm)
    gp = geo.params
    c_geo = 1.0 / (gp.rho_l * gp.eps_l) - 1.0 / gp.tau_f
    T0 = float(pm.mat[T0_INDEX])
    eps_l = p.eps_l
    dv = 1e-3 * x_e
    # the branch's force of a uniform unit P, read off the full model (without R_s, whose
    # V_d state the force does not see; the same kinematics as the plain twin's)
    mp = (DFAModel(model.params.replace(R_s=0.0)) if model.series else model) if model.polarized else None
    for k, x in enumerate(xg):
        y0 = _uniform(pm, x)
        fv = pm.electrostatic_force(y0, V_REF)
        tab[k, sk.C0] = fv / V_REF ** 2
        iv = _current(pm, x, V_REF, None, 0.0)
        tab[k, sk.I0] = iv / V_REF
        tab[k, sk.J0] = (_current(pm, x, V_REF, None, dv) - iv) / (dv * V_REF)
        tab[k, sk.CAP] = pm.diagnostics(state(pm, x), V_REF)[0][R_C]
        rates = geo.rhs(_uniform(geo, x), V_REF, 0.0)[nb:nb + N]
        tab[k, sk.NFIX:sk.NFIX + n] = rates / (c_geo * gp.eps_l * V_REF)
        lz = float(pm.kin.lz(x))
        if lz >= p.l_e:
            continue
        sq = _unzipped_positions(lz, p.l_e, s_pts)
        u, G = _profile_on(pm, x, sq)
        g = G / (u * u)
        I1, I2, I2o = hat_integrals(s_pts, sq, g)
        K = tab[k, sk.C0] / (eps_l ** 2 * np.trapezoid(g, sq))     # the full model's own scale
        tab[k, C1:C1 + n] = -2.0 * K * eps_l * T0 * I1
        tab[k, C2:C2 + n] = K * T0 * T0 * I2
        tab[k, C2O:C2O + n] = K * T0 * T0 * I2o
        if mp is not None:
            tab[k, sk.NFIX + n:sk.NFIX + 3 * n] = _polarization_row(mp, x, s_pts, sq, G)
    # the current's weights: a node at a time on a coarser grid (they only enter the
    # current and, behind R_s, V_d), interpolated
    xc = np.linspace(0.0, x_e, min(N_CURRENT, n_grid))
    W = np.zeros((len(xc), 2 * n))
    for k, x in enumerate(xc):
        for i in range(n):
            q = np.zeros(N)
            q[i] = qs
            ic = _current(pm, x, 0.0, q, 0.0)
            W[k, i] = ic / qs
            W[k, n + i] = (_current(pm, x, 0.0, q, dv) - ic) / (dv * qs)
    for c in range(2 * n):
        tab[:, IQ + c] = np.interp(xg, xc, W[:, c])
    tab[:, sk.DLZ] = pm.kin.dlz_dx(xg)
    tab[:, sk.LZ] = pm.kin.lz(xg)
    # the layer's columns are never read in the lattice form: the zipped material's point
    tab[:, sk.IUF] = 1.0 / u0(pm)
    tab[:, sk.T0F] = T0
    tab[:, sk.IUA] = 1.0 / u0(pm)
    tab[:, sk.WF] = 1.0
    return xg, tab


def _polarization_row(m: DFAModel, x: float, s_pts, sq, G) -> np.ndarray:
    """[D, O] at stroke x: the branch's force sum_i D_i P_i^2 + 2 sum_i O_i P_i P_(i+1). Its
    energy t_l P^2 / (2 chi_p eps_l) gives c int (dt_l/dx) P(s)^2 ds over the unzipped
    length (G = dt_l/dx at the positions sq), P(s) linear between the nodes
    (hat_integrals), c read off the full model m's force with a uniform P (V = 0, q = 0:
    no P-q or P-V terms)."""
    N, nb = m.params.N, m.nbord
    norm = np.trapezoid(G, sq)
    if not abs(norm) > 0:
        return np.zeros(2 * N)
    y = m.initial_state(x)
    y[nb + N:nb + 2 * N] = 1.0
    c = m.electrostatic_force(y, 0.0) / norm        # the force of a uniform unit P
    _, I2, I2o = hat_integrals(s_pts, sq, G)
    return np.r_[c * I2, c * I2o]
