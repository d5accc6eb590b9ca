"""One entry point per kernel for all schemes (ids: 0 continuum-p0, 1 paper, 2 continuum)."""
from __future__ import annotations

from .._jit import njit

from ..physics.equations import C_SCHEME, diagnostics as diag_elem, factor as factor_blk, jacobian as jac_blk, rhs as rhs_elem
from ..physics.equations import solve as solve_blk
from ..physics.nodal import diagnostics_p1, factor_p1, jacobian_p1, rhs_p1, solve_p1

P0_SCHEME, PAPER, NODAL = 0, 1, 2


@njit(cache=True, _nrt=False)
def rhs(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work, tri, jbe):
    if cfg[C_SCHEME] == NODAL:
        return rhs_p1(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, False, tri, jbe, work)
    return rhs_elem(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work)


@njit(cache=True, _nrt=False)
def jacobian(cfg, geo, mat, law, lawp, V, F, y, f0, Jee, Jeb, Jbe, Jbb, tri, kin, work, tmp, ytmp, jbe):
    if cfg[C_SCHEME] == NODAL:
        return jacobian_p1(cfg, geo, mat, law, lawp, V, F, y, f0, tri, Jeb, Jbe, Jbb, kin, tmp, ytmp, work, jbe)
    return jac_blk(cfg, geo, mat, law, lawp, V, F, y, f0, Jee, Jeb, Jbe, Jbb, kin, work, tmp, ytmp)


@njit(cache=True, _nrt=False)
def factor(cfg, mat, gh, Jee, Jeb, Jbe, Jbb, tri, fb, Winv, zeta, cp, dinv, S):
    if cfg[C_SCHEME] == NODAL:
        factor_p1(cfg, mat, gh, tri, Jeb, Jbe, Jbb, fb, cp, dinv, zeta, S)
    else:
        factor_blk(cfg, gh, Jee, Jeb, Jbe, Jbb, fb, Winv, zeta, S)


@njit(cache=True, _nrt=False)
def solve(cfg, mat, gh, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, r, out):
    if cfg[C_SCHEME] == NODAL:
        solve_p1(cfg, mat, gh, tri, cp, dinv, zeta, Jbe, Jbb, S, fb, r, out)
    else:
        solve_blk(cfg, gh, Winv, zeta, Jbe, S, fb, r, out)


@njit(cache=True, _nrt=False)
def diagnostics(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, rec, P):
    if cfg[C_SCHEME] == NODAL:
        diagnostics_p1(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, rec, P, work)
    else:
        diag_elem(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, rec, P)


# The same kernels on bundles, for the integrator's pieces: M = (cfg, geo, mat, law, lawp)
# the model's arrays, wk = (kin, work, tri, jbe) its scratch, ws the workspace
# (integrator.make_workspace: Jee, Jeb, Jbe, Jbb, Winv, zeta, tri, jbe, cp, dinv, S, f).
# Inlined: a call layer of its own on the hottest path cost ~8 % of a run
@njit(cache=True, _nrt=False, inline="always")
def rhs_b(M, wk, V, F, y, ydot):
    return rhs(M[0], M[1], M[2], M[3], M[4], V, F, y, ydot, wk[0], wk[1], wk[2], wk[3])


@njit(cache=True, _nrt=False, inline="always")
def diagnostics_b(M, wk, V, dVdt, F, y, ydot, row, P):
    diagnostics(M[0], M[1], M[2], M[3], M[4], V, dVdt, F, y, ydot, wk[0], wk[1], row, P)


@njit(cache=True, _nrt=False, inline="always")
def jacobian_b(M, wk, ws, V, F, y, f0, tmp, ytmp):
    jacobian(M[0], M[1], M[2], M[3], M[4], V, F, y, f0, ws[0], ws[1], ws[2], ws[3], ws[6], wk[0], wk[1], tmp, ytmp,
             ws[7])


@njit(cache=True, _nrt=False, inline="always")
def factor_b(M, ws, gh, fb):
    factor(M[0], M[2], gh, ws[0], ws[1], ws[2], ws[3], ws[6], fb, ws[4], ws[5], ws[8], ws[9], ws[10])


@njit(cache=True, _nrt=False, inline="always")
def solve_b(M, ws, gh, fb, r, out):
    solve(M[0], M[2], gh, ws[4], ws[5], ws[2], ws[3], ws[6], ws[8], ws[9], ws[10], fb, r, out)
