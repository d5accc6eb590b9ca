"""The assembled model: one object holding the packed physics for the compiled kernels.

The same `DFAModel` serves simulation, statics, the CLI, sweeps, the FMU and the
surrogate fitting. Physics pieces are objects passed in (kinematics from the layout,
a resistivity law, a load); none of them touches the integrator.
"""
from __future__ import annotations

import numpy as np

from . import dielectrics, kinematics
from .equations import (B, CHI_P, DS, R_S, EPS_F, EPS_L, K, MASS, NMAT, NPOW, NREC, QSC, RHO_TS, T0, T_F, T_LZ, TAU_F,
                        TAU_L, TAU_P, U0, W, X_E, XSC)
from ..numerics.kernels import NODAL, P0_SCHEME, PAPER, diagnostics, rhs
from ..numerics.integrator import make_workspace
from .nodal import NWORK

SCHEME_IDS = {"continuum": NODAL, "continuum-p0": P0_SCHEME, "paper": PAPER}
from ..io.parameters import Parameters


# The device voltage's error weight, in units of the amplitude. Its R_s C transient after
# a switch lasts ns to ms; resolved to rtol it took ~70 steps per switch (the steps grow
# ~4 % each while a 12 kV jump decays to rtol), nearly all of a run's cost, though the
# stroke and charges - whose own error is controlled - depend on it only through its
# integral. 30 times looser it takes half the steps and the stroke's error stays at the
# tolerance (measured against rtol 1e-8, R_s = 1e2-1e7: 0.3-0.5 um max at rtol 1e-5, as
# before); 1e3 times looser let R_s = 1e7 (R_s C ~ ms: the device voltage's own error
# then carries on into the stroke) reach 2.3 um.
VD_SCALE = 30.0


class DFAModel:
    """Continuum DFA model of one actuator (see README, 'Numerics')."""

    def __init__(self, params: Parameters, law: dielectrics.ResistivityLaw | None = None):
        self.params = p = params
        self.kin = kinematics.make(p)
        self.law = law if law is not None else dielectrics.from_parameters(p)
        self.M = p.N - 1
        self.ds = p.l_e / self.M
        self.scheme_id = SCHEME_IDS[p.scheme]
        # the liquid's fast relaxation (nodal scheme): a second state per material point
        self.polarized = self.scheme_id == NODAL and p.chi_p > 0
        self.nb = 2 if (p.scheme == "paper" or self.polarized) else 1
        self.nbord = 1 if p.m == 0 else 2
        # element states: per element (block schemes) or per material point (nodal:
        # q' at every point, then P at every point when polarized)
        self.n_states = p.N * self.nb if self.scheme_id == NODAL else self.M * self.nb
        # a series resistance (nodal scheme): the device's voltage V_d is the last state
        self.series = self.scheme_id == NODAL and p.R_s > 0
        self.cfg = np.array([self.kin.layout_id, self.scheme_id, 1 if self.law.is_constant else 0, self.nb,
                             self.nbord, self.M, 1 if self.polarized else 0, 1 if self.series else 0],
                            dtype=np.int64)
        mat = np.zeros(NMAT)
        mat[EPS_L], mat[EPS_F], mat[T_F], mat[T_LZ] = p.eps_l, p.eps_f, p.t_f, p.t_lz
        mat[T0] = 2.0 * p.eps_l * p.t_f / p.eps_f
        mat[U0] = p.t_lz + mat[T0]
        mat[TAU_L] = p.tau_l if self.law.is_constant else np.nan
        mat[TAU_F] = p.tau_f
        mat[RHO_TS] = p.rho_t_s
        mat[B], mat[MASS], mat[K] = p.b, p.m, p.k
        mat[DS], mat[W] = self.ds, p.w
        mat[CHI_P], mat[TAU_P], mat[R_S] = p.chi_p, p.tau_p, p.R_s
        mat[XSC] = self.kin.x_e
        mat[X_E] = self.kin.x_e
        mat[QSC] = p.eps_l * 1000.0 / mat[U0]
        self.mat = mat
        self.geo = self.kin.geo
        self.n = self.nbord + self.n_states + (1 if self.series else 0)

    # ------------------------------------------------------------------ state
    def initial_state(self, x0: float = 0.0, V_before: float = 0.0) -> np.ndarray:
        """Uncharged actuator at rest at stroke x0 (behind a series resistance, its
        electrodes at V_before: the source's steady voltage before t = 0)."""
        y = np.zeros(self.n)
        y[0] = x0
        if self.series:
            y[-1] = V_before
        return y

    def device_voltage(self, y, V) -> float:
        """The voltage across the electrodes: V, or the state V_d behind a series resistance."""
        return float(y[-1]) if self.series else float(V)

    def workspace(self, h0: float):
        """Fresh integrator workspace and controller state (integrator.make_workspace)."""
        return make_workspace(self.n, self.M + 1, self.nb, float(h0))

    def force_jumps(self) -> np.ndarray:
        """Strokes at which the force is discontinuous: the paper scheme's midpoint
        crossings (the front passing an element midpoint). Empty for our schemes."""
        if self.scheme_id != PAPER:
            return np.empty(0)
        s = self.element_edges()
        mid = 0.5 * (s[:-1] + s[1:])
        return np.array([self.kin.x_of_lz(v) for v in mid])

    def element_edges(self) -> np.ndarray:
        return np.linspace(0.0, self.params.l_e, self.M + 1)

    def with_k(self, k_extra: float) -> np.ndarray:
        """mat with an extra linear stiffness (a load spring) added to k."""
        mat = self.mat.copy()
        mat[K] += k_extra
        return mat

    def scales(self, V_amp: float, energy: bool = False) -> np.ndarray:
        """Per-component scales used by the error norm (stroke, velocity, charge, device
        voltage: VD_SCALE looser unless the energy is booked, whose R_s I^2 needs the
        transient itself)."""
        sc = np.empty(self.n)
        sc[0] = self.mat[XSC]
        if self.nbord == 2:
            sc[1] = self.mat[XSC] * 100.0
        sc[self.nbord:] = self.params.eps_l * max(abs(V_amp), 100.0) / self.mat[U0]
        if self.series:
            sc[-1] = (1.0 if energy else VD_SCALE) * max(abs(V_amp), 100.0)
        return sc

    # ------------------------------------------------------------------ python-level evaluation
    def rhs(self, y, V, F, mat=None):
        """dy/dt at voltage V and load F (NumPy arrays in and out)."""
        ydot = np.empty(self.n)
        rhs(self.cfg, self.geo, self.mat if mat is None else mat, self.law.law_id, self.law.params,
            float(V), float(F), np.ascontiguousarray(y, dtype=float), ydot, np.zeros(6), np.zeros(NWORK),
            np.zeros((self.M + 1, 12)), np.zeros(4 * (self.M + 1) + 1))
        return ydot

    def electrostatic_force(self, y, V) -> float:
        """Zipping force -F_e (N, positive pulls towards zipping) at state y."""
        ydot = np.empty(self.n)
        Fe = rhs(self.cfg, self.geo, self.mat, self.law.law_id, self.law.params, float(V), 0.0,
                 np.ascontiguousarray(y, dtype=float), ydot, np.zeros(6), np.zeros(NWORK),
                 np.zeros((self.M + 1, 12)), np.zeros(4 * (self.M + 1) + 1))
        return -Fe

    def diagnostics(self, y, V, F=0.0, dVdt=0.0, mat=None):
        """Derived quantities and powers at state y: (record row, powers)."""
        mat = self.mat if mat is None else mat
        y = np.ascontiguousarray(y, dtype=float)
        ydot = self.rhs(y, V, F, mat)
        row = np.zeros(NREC)
        P = np.zeros(NPOW)   # every power slot equations.write_outputs fills (6 had lost the last)
        diagnostics(self.cfg, self.geo, mat, self.law.law_id, self.law.params, float(V), float(dVdt), float(F),
                    y, ydot, np.zeros(6), np.zeros(NWORK), row, P)
        return row, P

    def charges(self, y, V):
        """(s, sigma_l, sigma_f) along the electrode: at the material points (nodal
        scheme) or element midpoints (block schemes)."""
        y = np.asarray(y)
        s = self.element_edges()
        if self.scheme_id == PAPER:
            e = y[self.nbord:].reshape(self.M, 2)
            return 0.5 * (s[:-1] + s[1:]), e[:, 0], e[:, 1]
        if self.scheme_id == NODAL:
            q = y[self.nbord:self.nbord + self.params.N]   # q' (with P when polarized)
        else:
            q = y[self.nbord:]
            s = 0.5 * (s[:-1] + s[1:])
        u = self.mat[T0] + self.kin.t_l(s, y[0])
        sigma_l = (self.params.eps_l * self.device_voltage(y, V) - self.mat[T0] * q) / u
        return s, sigma_l, sigma_l + q
