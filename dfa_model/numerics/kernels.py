"""One entry point per kernel for all schemes (ids: 0 continuum-p0, 1 paper, 2 continuum)."""
from __future__ import annotations

from .._jit import njit

from ..physics.equations import C_SCHEME, diagnostics as diag_elem, factor as factor_blk, jacobian as jac_blk, rhs as rhs_elem
from ..physics.equations import solve as solve_blk
from ..physics.nodal import diagnostics_p1, factor_p1, jacobian_p1, rhs_p1, solve_p1

P0_SCHEME, PAPER, NODAL = 0, 1, 2


@njit(cache=True)
def rhs(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work, tri, jbe):
    if cfg[C_SCHEME] == NODAL:
        return rhs_p1(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, False, tri, jbe, work)
    return rhs_elem(cfg, geo, mat, law, lawp, V, F, y, ydot, kin, work)


@njit(cache=True)
def jacobian(cfg, geo, mat, law, lawp, V, F, y, f0, Jee, Jeb, Jbe, Jbb, tri, kin, work, tmp, ytmp, jbe):
    if cfg[C_SCHEME] == NODAL:
        return jacobian_p1(cfg, geo, mat, law, lawp, V, F, y, f0, tri, Jeb, Jbe, Jbb, kin, tmp, ytmp, work, jbe)
    return jac_blk(cfg, geo, mat, law, lawp, V, F, y, f0, Jee, Jeb, Jbe, Jbb, kin, work, tmp, ytmp)


@njit(cache=True)
def factor(cfg, mat, gh, Jee, Jeb, Jbe, Jbb, tri, fb, Winv, zeta, cp, dinv, S):
    if cfg[C_SCHEME] == NODAL:
        factor_p1(cfg, mat, gh, tri, Jeb, Jbe, Jbb, fb, cp, dinv, zeta, S)
    else:
        factor_blk(cfg, gh, Jee, Jeb, Jbe, Jbb, fb, Winv, zeta, S)


@njit(cache=True)
def solve(cfg, mat, gh, Winv, zeta, Jbe, Jbb, tri, cp, dinv, S, fb, r, out):
    if cfg[C_SCHEME] == NODAL:
        solve_p1(cfg, mat, gh, tri, cp, dinv, zeta, Jbe, Jbb, S, fb, r, out)
    else:
        solve_blk(cfg, gh, Winv, zeta, Jbe, S, fb, r, out)


@njit(cache=True)
def diagnostics(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, rec, P):
    if cfg[C_SCHEME] == NODAL:
        diagnostics_p1(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, rec, P, work)
    else:
        diag_elem(cfg, geo, mat, law, lawp, V, dVdt, F, y, ydot, kin, work, rec, P)
