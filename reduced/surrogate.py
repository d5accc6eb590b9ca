"""A surrogate: a few states, tabulated maps of the stroke, a fast path and python-control.

All families share one structure (dfa_model/numerics/surrogate_kernel.py; the states are named
in `state_names`):

    x        stroke (m)                         b dx/dt = F_e - F - k x   (m = 0)
    v        stroke velocity (m/s), with a mass  m dv/dt = F_e - F - k x - b v
    V_d      device voltage behind a series resistance R_s (V)
    q_f      the front layer's interface charge (C/m^2): the material just beyond the
             zipping front, through which the force acts; an effective material point
             whose rates are the full model's force-weighted charge's (frozen.front_point),
             renewed as the front moves by the material it moves onto
    P_f      its polarization (C/m^2), with the polarization branch
    q_i      the interface charge of material point i (C/m^2), i = 1..n, at s_i along
             the electrode: the charge history the front comes back to
    P_i      their polarization, with the branch

    F_e = c0(x) V_d^2 + c1(x) V_d q_f + c2(x) q_f^2 + c3(x) P_f^2
    current  the source current: (V - V_d)/R_s behind a series resistance, else
             C(x) dV/dt + dx/dt (j0 V + j1 q_f) + i0 V + i1 q_z (q_z: the zipped points' mean)

with stops at x = 0 and x_e. The families differ in where the maps come from (see
families.py). Inputs `voltage`, `force`; outputs `stroke`, `current`.

The lattice family has no q_f: its points sit at the full model's nodes (q_i, P_i at every
node), and the force and current are read off them:

    F_e = c0(x) V_d^2 + sum_i (c1_i(x) V_d q_i + c2_i(x) q_i^2 + 2 o_i(x) q_i q_(i+1)) + (P's form)
    current  C(x) dV/dt + dx/dt (j0 V + sum_i jq_i q_i) + i0 V + sum_i iq_i q_i
"""
from __future__ import annotations

import json
import math
import threading
import time
import warnings
from functools import cached_property

import numpy as np

from dfa_model import limits
from dfa_model.numerics import surrogate_kernel as sk
from dfa_model.physics.dielectrics import from_parameters
from dfa_model.io.parameters import Parameters
from dfa_model.io.results import StrokeMetrics
from dfa_model.numerics.solver import protocol_load
from dfa_model.numerics.trace import StrokeTrace
from dfa_model.waveforms import Load, Protocol, segment_key, segments

from . import fast_inversions

FORMAT = "dfa-surrogate"
VERSION = 8     # 8: no fixed-material gap column (7: the advection kept within the lag, c_adv; 6: the material
                # lag c_m, the layer frozen within it; 5: the behind wake's source interpolated; 4: material
                # points + the front layer)
GIU_V7 = 15     # the column version 7 had after the fixed ones' first 15 (the fixed material's gap slope)
V_S_REL = 1e-8        # the front's side blends over v_s = V_S_REL l_e per second: continuous, all but sharp
RTOL = 1e-4           # the fast path's tolerance: the stroke's local error bound is rtol (x + x_e)
# the lattice family's: its own error is 0.04 % of range (rtol 1e-4), and over the development
# panel's 84 cells (Table 1, 15 deg, Peano x plain, branch, Eq. (21), all) 5e-4 took 25 % fewer
# steps (the standard protocol: 83 against 132) for a mean stroke RMS of 0.07 % against 0.04
# (largest 0.28 against 0.19 %; 1e-3: 1.2 % on a 10 Hz train). docs/guide/surrogates.md
RTOL_LATTICE = 5e-4
P_SCALE = 0.3         # the polarizations' error scale over chi_p times the charges' (Surrogate.scales)


_SCRATCH = threading.local()
_SCRATCH_ROWS = 1 << 16     # a reusable record buffer up to 5 MB per thread; longer runs allocate their own


def _record_buffer(rows: int) -> np.ndarray:
    """An output buffer of at least `rows` rows: this thread's reused one when it is small
    (allocating and unmapping a fresh one was ~3 % of a standard-protocol run); the
    rows a run fills are copied out of it."""
    if rows > _SCRATCH_ROWS:
        return np.empty((rows, sk.NREC))
    buf = getattr(_SCRATCH, "rec", None)
    if buf is None or buf.shape[0] < rows:
        buf = _SCRATCH.rec = np.empty((max(rows, 4096), sk.NREC))
    return buf


class SurrogateError(RuntimeError):
    """The surrogate's integration stopped early."""


class SurrogateResult(StrokeMetrics):
    """Time series of a surrogate run (every accepted step) and the full model's metrics
    (StrokeMetrics: unzipping speed, static stroke, ripple, drift...). `y_end`: the final
    kernel state (to continue from, as y0)."""

    def __init__(self, surrogate, protocol, rec, wall_time, steps, y_end, load=None):
        self.surrogate = surrogate
        self.params = surrogate.params
        self.load = load if load is not None else Load(0.0)
        self.protocol = protocol
        self.rec = rec
        self.wall_time = wall_time
        self.n_steps = steps
        self.y_end = y_end
        self.averaged_windows = []      # (t0, t1) integrated cycle-averaged (simulate's `inversions`)
        self.t, self.x, self.v = rec[:, sk.R_T], rec[:, sk.R_X], rec[:, sk.R_V]
        self.q_f, self.P_f, self.V_d = rec[:, sk.R_QF], rec[:, sk.R_PF], rec[:, sk.R_VD]
        self.V, self.F, self.I, self.Fe = rec[:, sk.R_VOLT], rec[:, sk.R_F], rec[:, sk.R_I], rec[:, sk.R_FE]

    @cached_property
    def trace(self) -> StrokeTrace:
        """The stroke joined linearly between the recorded steps (built on first use)."""
        return StrokeTrace.from_samples(self.t, self.x)

    def summary(self) -> dict:
        return {"static_stroke": self.static_stroke, "final_stroke": self.final_stroke,
                "unzipping_speed": self.unzipping_speed, "wall_time": self.wall_time, "steps": self.n_steps}


class Surrogate:
    """A fitted low-order model of one actuator (see the module docstring).

    family   'lattice', 'charge' or 'lumped' (families.py)
    params   the actuator (dfa_model Parameters) the maps were computed for
    x_grid, tables  the maps of the stroke (dfa_model.numerics.surrogate_kernel columns; the
             material points' inverse gaps last)
    n_points the number of material points (0: none, the layer alone)
    c_ell    the front renews its layer as it moves by ell(x) = c_ell w_f(x) (w_f: the
             layer's width, a table column); inf: never (the lumped circuit)
    c_w      the wakes' width over the layer's (their renewal length; the ahead wake's
             mean gap column is computed for it)
    c_m      the material lag over the layer's width: the layer's material follows the
             front only once the front is c_m w_f from it (a play; 0: at once): within the
             lag the front's motion does not mix the wakes into the layer and moves its
             charge along the material at c_adv of the renewal's advection
    c_adv    the share of the advection kept within the lag (1: all; 0: the layer frozen,
             which calls unstable DC loops stable)
    info     provenance: how the maps were built and fitted, training errors
    """

    def __init__(self, family, params: Parameters, x_grid, tables, n_points=0, c_ell=1.2, info=None, c_w=2.0,
                 v_s=None, c_m=0.0, c_adv=1.0):
        self.family = family
        self.params = params
        self.x_grid = np.ascontiguousarray(x_grid, dtype=float)
        self.tables = np.ascontiguousarray(tables, dtype=float)
        self.n_points = int(n_points)
        if self.n_points == 1 or self.n_points < 0:
            raise ValueError(f"n_points: got {n_points!r}, expected 0 or at least 2")
        # per material point its inverse gap, and with the polarization branch the weights
        # of its P in the force (frozen.polarization_weights)
        cols = sk.NFIX + self.n_points * ((3 + sk.NLAT) if self.lattice else
                                          (3 if params.chi_p > 0 and self.n_points else 1))
        if self.tables.shape != (len(self.x_grid), cols):
            raise ValueError(f"tables: expected shape ({len(self.x_grid)}, {cols}), got {self.tables.shape}")
        self.x_e = float(self.x_grid[-1])
        self.c_ell = float(c_ell)
        self.c_w = float(c_w)
        self.c_m = float(c_m)
        self.c_adv = float(c_adv)
        # the speed over which the front's side blends (dl_z/dt, m/s): a scale, not a fit
        self.v_s = float(v_s) if v_s is not None else V_S_REL * params.l_e
        self.info = dict(info or {})
        law = from_parameters(params)
        self._law, self._lawp = int(law.law_id), np.ascontiguousarray(law.params, dtype=float)
        self._inputs = {}       # _kernel_inputs
        self._plans = {}        # _plan

    # ------------------------------------------------------------------ structure
    @property
    def rtol(self) -> float:
        """simulate's default tolerance (RTOL; the lattice family's RTOL_LATTICE). The
        sampled paths (the compiled hold, system(dt)) take a step or two per sample whatever
        the tolerance, and keep RTOL: at RTOL_LATTICE a random Peano's 10 Hz hold tracked
        at 1.19x the full model's RMS, at RTOL 1.00x, in the same time."""
        return RTOL_LATTICE if self.lattice else RTOL

    @property
    def lattice(self) -> bool:
        """The lattice form: a material point at every node of the full model's lattice,
        the force and current read off the points (no front layer, no wakes)."""
        return self.family == "lattice"

    @property
    def has_mass(self) -> bool:
        return self.params.m > 0

    @property
    def polarized(self) -> bool:
        return self.params.chi_p > 0

    @property
    def series(self) -> bool:
        return self.params.R_s > 0

    @property
    def has_wakes(self) -> bool:
        """The wakes behind and ahead of the layer are states (with material points and a
        finite renewal length)."""
        return self.n_points >= 2 and np.isfinite(self.c_ell) and not self.lattice

    @property
    def ny(self) -> int:
        """Length of the kernel's state vector (the inputs V, F last)."""
        return sk.NODE0 + 2 * self.n_points + 2

    @cached_property
    def _names(self):
        """(name, kernel index) of every state this actuator has, in order."""
        n = self.n_points
        pol = self.polarized
        out = [("x", sk.X)] + ([("v", sk.VEL)] if self.has_mass else []) + \
            ([("V_d", sk.VD)] if self.series else [])
        if not self.lattice:
            out += [("q_f", sk.QF)] + ([("P_f", sk.PF)] if pol else [])
        if self.has_wakes:
            out += [("q_b", sk.QB)] + ([("P_b", sk.PB)] if pol else []) + [("q_a", sk.QA)] + \
                ([("P_a", sk.PA)] if pol else [])
        out += [(f"q_{i + 1}", sk.NODE0 + i) for i in range(n)]
        if self.polarized:
            out += [(f"P_{i + 1}", sk.NODE0 + n + i) for i in range(n)]
        return out

    @property
    def state_names(self) -> list[str]:
        return [name for name, _ in self._names]

    @property
    def n_states(self) -> int:
        return len(self._names)

    def _index(self):
        """Positions of the named states in the kernel's state vector."""
        return [i for _, i in self._names]

    def _kernel_inputs(self, averaged=False, k_extra=0.0, V_amp=None, lag=True):
        """(par, scales) for the kernel, kept between calls (the kernels only read them):
        rebuilt when anything they are made of changed (the attributes are public)."""
        key = (bool(averaged), float(k_extra), V_amp, lag, self.c_ell, self.c_w, self.c_m, self.c_adv, self.v_s,
               self.n_points, self.x_e, self._law)
        hit = self._inputs.get(key)
        if hit is not None and hit[0] is self.params:
            return hit[1], hit[2]
        if len(self._inputs) > 32:
            self._inputs.clear()
        par = self.par(averaged, k_extra, lag)
        sc = self.scales(V_amp) if V_amp is not None else None
        self._inputs[key] = (self.params, par, sc)
        return par, sc

    def par(self, averaged=False, k_extra=0.0, lag=True) -> np.ndarray:
        """The kernel's parameter vector. lag=False: without the material lag (c_m), whose
        play the compiled stepper renews between its steps (the kernel's _replay): the
        continuous-time evaluations (python-control, the equilibria, the input gains) have
        no such hook, and renew the layer at the front's speed as c_m = 0 does."""
        p = self.params
        out = np.zeros(sk.NPAR)
        out[sk.P_XE], out[sk.P_B], out[sk.P_M], out[sk.P_K] = self.x_e, p.b, p.m, p.k + k_extra
        out[sk.P_RS], out[sk.P_CHI], out[sk.P_TAUP] = p.R_s, p.chi_p, p.tau_p
        out[sk.P_TAUF], out[sk.P_EPSL] = p.tau_f, p.eps_l
        out[sk.P_T0] = 2.0 * p.eps_l * p.t_f / p.eps_f
        out[sk.P_ICELL] = 0.0 if not np.isfinite(self.c_ell) else 1.0 / self.c_ell
        out[sk.P_AVG] = 1.0 if averaged else 0.0
        out[sk.P_N], out[sk.P_LE] = self.n_points, p.l_e
        const = self._law == 0
        out[sk.P_CONST] = 1.0 if const else 0.0
        out[sk.P_ITAUL] = 1.0 / (p.rho_l * p.eps_l) if const else 0.0
        out[sk.P_IWB] = 1.0 / self.c_w
        out[sk.P_VS] = self.v_s
        out[sk.P_DM] = self.c_m if (lag and self.has_wakes) else 0.0
        out[sk.P_ADV] = self.c_adv
        out[sk.P_IU0] = 1.0 / (p.t_lz + out[sk.P_T0])
        out[sk.P_LAT] = 1.0 if self.lattice else 0.0
        return out

    def q_scale(self) -> float:
        p = self.params
        return p.eps_l * 1000.0 / (p.t_lz + 2.0 * p.eps_l * p.t_f / p.eps_f)

    def scales(self, V_amp: float = 1000.0) -> np.ndarray:
        """The error norm's scales per kernel state (the inputs last, unused)."""
        sc = np.ones(self.ny)
        qs = self.q_scale() * 10.0 * max(abs(V_amp), 100.0) / 1000.0
        sc[sk.X], sc[sk.VEL], sc[sk.VD] = self.x_e, self.x_e * 100.0, max(abs(V_amp), 100.0)
        sc[sk.QF:sk.NODE0] = qs
        # the material lag's anchor is a memory renewed between steps (its rate is 0)
        sc[sk.SM] = 1.0
        n = self.n_points
        sc[sk.NODE0:sk.NODE0 + 2 * n] = qs
        # the polarizations on their own scale, P_SCALE chi_p of the charges': on the
        # charges' own, the branch's DC creep ended 11-18 um from a converged run (Table 1,
        # 6 kV, 20 s; its error accumulates in the P the force reads over the unzipped
        # length); on this one within 0.1-0.9 um, in 1.3-3x fewer steps than a tenth of
        # the tolerance on everything (docs/guide/surrogates.md, breakdown 5)
        if self.params.chi_p > 0:
            sP = qs * P_SCALE * self.params.chi_p
            sc[sk.PF], sc[sk.PB], sc[sk.PA] = sP, sP, sP
            sc[sk.NODE0 + n:sk.NODE0 + 2 * n] = sP
        return sc

    # ------------------------------------------------------------------ fast path
    def simulate(self, protocol, load=None, duration=None, *, rtol=None, y0=None, max_steps=limits.MAX_STEPS,
                 averaged=None, inversions="average") -> SurrogateResult:
        """Run a protocol on the compiled path (dfa_model.numerics.surrogate_kernel). `protocol` and
        `load` as in dfa_model.simulate. `y0`: initial state by name ({'x': ..., 'q_f': ...},
        state_names) or a kernel state vector; default uncharged at rest at x = 0.
        `averaged`: the mean square voltage per segment for the cycle-averaged form
        (averaged.py), else None. `inversions`: 'average' (default) integrates a stage of
        fast full-duty polarity inversion cycle-averaged but for its last periods
        (fast_inversions: where the period is under 1 % of every electrical time constant;
        the result's averaged_windows lists where), 'step' steps every inversion. `rtol`:
        the stroke's local error bound per step, rtol (x + x_e); None: the family's
        (Surrogate.rtol: 1e-4, the lattice's 5e-4)."""
        if not isinstance(protocol, Protocol):
            if duration is None:
                raise ValueError("duration: required when the protocol is a plain voltage or waveform")
            protocol = Protocol.dc(protocol, duration) if isinstance(protocol, (int, float)) else \
                Protocol.single(protocol, duration)
        load = protocol_load(protocol, load)
        rtol = self.rtol if rtol is None else rtol
        if not (isinstance(rtol, (int, float)) and 1e-10 <= rtol <= 0.1):
            raise ValueError(f"rtol: got {rtol!r}, expected a number in [1e-10, 0.1]")
        if inversions not in ("average", "step"):
            raise ValueError(f"inversions: got {inversions!r}, expected 'average' or 'step'")
        t0 = time.perf_counter()
        plan = self._plan(protocol, load) if averaged is None and inversions == "average" else None
        if plan is not None:
            def run_kernel(seg, y, avg):
                return self._run(*seg[:6], y, rtol, max_steps, avg, load.k_load, protocol.amplitude, seg[6])
            rec, steps, y_end, windows = fast_inversions.run(self, plan, lambda: self._segments(protocol, load),
                                                             self._y0(y0), run_kernel)
        else:
            tb, v0, vs, f0, fs = self._segments(protocol, load)
            w2 = v0 * v0 if averaged is None else np.asarray(averaged, float)
            windows = []
            rec, steps, y_end = self._run(tb, v0, vs, f0, fs, w2, self._y0(y0), rtol, max_steps, averaged is not None,
                                          load.k_load, protocol.amplitude)
        res = SurrogateResult(self, protocol, rec, time.perf_counter() - t0, steps, y_end, load)
        res.averaged_windows = windows
        return res

    def _plan(self, protocol, load):
        """fast_inversions.plan, kept for the protocols of recent calls (keyed as their input
        segments are; rebuilt when the parameters were replaced)."""
        key = segment_key(protocol, load)
        hit = self._plans.get(key) if key is not None else None
        if hit is not None and hit[0] is self.params:
            return hit[1]
        plan = fast_inversions.plan(self, protocol, load)
        if key is not None:
            if len(self._plans) > 16:
                self._plans.clear()
            self._plans[key] = (self.params, plan)
        return plan

    def _segments(self, protocol, load):
        """The kernel's input segments (dfa_model.waveforms.segments: shared with the full
        model's runs of the same protocol in this process)."""
        return segments(protocol, load)

    def _y0(self, y0):
        y = np.zeros(self.ny)
        if y0 is None:
            return y
        if isinstance(y0, dict):
            pos = dict(self._names)
            for k, v in y0.items():
                if k not in pos:
                    raise ValueError(f"y0: unknown state {k!r}; this surrogate's states are "
                                     f"{', '.join(self.state_names)}")
                y[pos[k]] = float(v)
        else:
            y0 = np.asarray(y0, float).ravel()
            if y0.size != self.ny:
                raise ValueError(f"y0: a kernel state vector has {self.ny} entries, got {y0.size}")
            y[:] = y0
        if not np.all(np.isfinite(y)):
            raise ValueError("y0: must be finite")
        if not (0.0 <= y[0] <= self.x_e):
            raise ValueError(f"y0: stroke x = {y[0]:g} m outside [0, x_e = {self.x_e:g}] m")
        return y

    def _run(self, tb, v0, vs, f0, fs, w2, y, rtol, max_steps, averaged, k_extra=0.0, V_amp=1000.0, gof=None):
        par, sc = self._kernel_inputs(averaged, k_extra, float(V_amp))
        if gof is None:
            gof = np.zeros((len(v0), 2))
        cap = min(64 + 40 * len(v0), 4_000_000)
        h0 = min(1e-4, float(tb[-1] - tb[0]))
        while True:
            rec = _record_buffer(cap)
            status, rows, steps, y_end = sk.integrate(tb, v0, vs, f0, fs, w2, gof, y, self.tables, par, self._law,
                                                      self._lawp, sc, float(rtol), h0, rec, int(max_steps))
            if status == sk.FULL and cap < 16_000_000:
                cap = 4 * max(cap, rec.shape[0])
                continue
            break
        if status != sk.OK:
            why = {sk.FULL: "the output buffer is full", sk.MAX_STEPS: f"the step limit ({max_steps}) was reached",
                   sk.NONFINITE: "the solution became non-finite"}[status]
            raise SurrogateError(f"surrogate integration stopped at t = {rec[rows - 1, 0]:g} s: {why}")
        return rec[:rows].copy(), steps, y_end

    # ------------------------------------------------------------------ python-control
    def _eval(self, xs, V, F, W=None, vdot=0.0):
        y = np.zeros(self.ny)
        y[self._index()] = xs
        y[-2], y[-1] = V, F
        ydot = np.zeros(self.ny)
        par = self._kernel_inputs(lag=False)[0]
        Fe, I = sk.evaluate(y, V * V if W is None else W, float(vdot), self.tables, par, self._law, self._lawp, ydot,
                            sk.AUTO)
        return ydot[self._index()], I

    def capacitance(self, x):
        """The device capacitance at stroke x (F; x a number or an array, clamped to
        [0, x_e]): the maps' column, linear between its grid points (the kernel's
        capacitive current interpolates it cubically; C(x) is smooth on the grid)."""
        c = np.interp(np.clip(x, 0.0, self.x_e), self.x_grid, self.tables[:, sk.CAP])
        return float(c) if np.ndim(c) == 0 else c

    def input_gains(self, x: float) -> dict:
        """dq/dt per volt of each charge state at stroke x, uncharged ({name: C/m^2/s/V}):
        the averaged form's charge offsets (averaged.py)."""
        y = np.zeros(self.ny)
        y[sk.X] = min(max(x, 0.0), self.x_e)
        a, b = np.zeros(self.ny), np.zeros(self.ny)
        par = self.par(lag=False)
        y[-2] = 0.0
        if self.series:
            y[sk.VD] = 0.0
        sk.evaluate(y, 0.0, 0.0, self.tables, par, self._law, self._lawp, a, sk.HELD)
        y[-2] = 1.0
        if self.series:
            y[sk.VD] = 1.0
        sk.evaluate(y, 1.0, 0.0, self.tables, par, self._law, self._lawp, b, sk.HELD)
        return {name: float(b[i] - a[i]) for name, i in self._names if name[0] in "qP"}

    OUTPUTS = ("stroke", "current_no_ramp", "capacitance")
    OUTPUT_UNITS = {"stroke": "m", "current_no_ramp": "A", "capacitance": "F", "voltage": "V", "force": "N"}

    def state_units(self) -> dict:
        """The SI unit of each state (by state_names)."""
        unit = {"x": "m", "v": "m/s", "V_d": "V"}
        return {n: unit.get(n, "C/m^2") for n in self.state_names}

    def state_scale(self, V_ref: float = 6000.0) -> dict:
        """The scale of each state in system(scaled=True): a state there is its SI value
        over this (the stroke over x_e, charges over the charge a zipped layer takes at
        V_ref, ...), so every state is of order one and python-control's default
        tolerances (rtol 1e-3, atol 1e-6 in solve_ivp) hold for all of them."""
        sc = self.scales(V_ref)
        return {n: float(sc[i]) for n, i in self._names}

    def system(self, name=None, scaled=True, V_ref: float = 6000.0, dt=None):
        """This surrogate as a control.NonlinearIOSystem: inputs voltage (V), force (N);
        outputs stroke (m), current_no_ramp (A), capacitance (F); states `state_names`.

        dt (s): a discrete-time system sampled every dt with the inputs held over each
        sample (zero-order hold, as a digital controller or a DAQ drives the actuator):
        each update runs the compiled stepper over one sample, so it is the fast path's
        own answer at python-control's defaults (no solve_ivp) and keeps the front layer's
        material lag (its play anchor is the extra state `s_m`, m of zipped length); loops
        built on it with control.interconnect and discrete controllers of the same dt
        lose a hold where the fast path does (sampled_system). Its states are scaled like
        the continuous system's: `sys.scaled_state(s.equilibrium(V, F))` turns SI values
        into them. For poles and margins linearize the continuous system (linearize()):
        the play is not smooth, and a difference quotient of the sampled update depends on
        where its anchor sits (at the lag's rest, Table 1 at 6 kV, 4 N: |eig| up to
        1.00006 per 10 ms; at the lag's edge 0.999998).

        scaled=True (default): each state is its SI value over state_scale(V_ref), so
        no state sits below solve_ivp's default atol. The system is stiff (the stroke's
        pole ~ -345 1/s, the charges' 1e-4 to 0.1 1/s): solve it with
        solve_ivp_method='LSODA' (within 0.11 um on 6 kV DC at default tolerances, 5x
        faster than RK45); python-control's default RK45 is 11-45 um off there (1-4 %,
        its chatter at the stability limit rectified by the front's renewal), or pass
        solve_ivp_kwargs={'rtol': 1e-6}. A tolerance is no stability verdict for a closed
        loop (docs/guide/surrogates.md).

        `current_no_ramp` is the source current at a constant input voltage (the motion
        and conduction currents; behind R_s, (V - V_d)/R_s, the whole source current):
        without R_s, a ramping source also delivers capacitance * dV/dt, which a system
        whose inputs carry no derivative cannot know. Units: the returned
        system's `units` (signals) and `state_units` (SI) attributes.

        Equilibria: use equilibrium() (strokes bounded to [0, x_e], the first balance
        from x = 0); control.find_operating_point is unbounded and may return a stroke
        outside the actuator."""
        import control
        if dt is not None:
            return self.sampled_system(dt, name, scaled, V_ref)
        names = self.state_names
        scale = self.state_scale(V_ref)
        S = np.array([scale[n] for n in names]) if scaled else np.ones(len(names))

        def upd(t, xs, u, params):
            return self._eval(xs * S, u[0], u[1])[0] / S

        def out(t, xs, u, params):
            xs = xs * S
            return np.array([min(max(xs[0], 0.0), self.x_e), self._eval(xs, u[0], u[1])[1], self.capacitance(xs[0])])

        sys_ = control.nlsys(upd, out, inputs=["voltage", "force"], outputs=list(self.OUTPUTS),
                             states=names, name=name or f"dfa_{self.family}")
        sys_.units = dict(self.OUTPUT_UNITS)
        sys_.state_units = self.state_units()
        sys_.state_scale = dict(zip(names, S.tolist()))
        return sys_

    def sampled_system(self, dt: float, name=None, scaled=True, V_ref: float = 6000.0):
        """system(dt=dt): the discrete-time system (see there). States `state_names`, then
        `s_m` when the layer has a material lag (its anchor, a memory the stepper renews);
        the update x[k+1] = the compiled run over [k dt, (k + 1) dt] from x[k] with the
        inputs u[k] held."""
        import control
        if not (isinstance(dt, (int, float)) and math.isfinite(dt) and 1e-6 <= dt <= 10.0):
            raise ValueError(f"dt: got {dt!r}, expected a sample period in [1e-6, 10] s")
        dt = float(dt)
        names, idx = self.state_names, self._index()
        lag = self.has_wakes and self.c_m > 0
        scale = self.state_scale(V_ref)
        S = np.array([scale[n] for n in names]) if scaled else np.ones(len(names))
        units = self.state_units()
        if lag:
            names, idx = names + ["s_m"], idx + [sk.SM]
            S = np.append(S, self.x_e if scaled else 1.0)
            units["s_m"] = "m"
        idx = np.asarray(idx)
        par, sc = self._kernel_inputs(False, 0.0, float(V_ref))
        seg = {k: np.zeros(n) for k, n in (("tb", 2), ("v0", 1), ("vs", 1), ("f0", 1), ("fs", 1), ("w2", 1))}
        gof = np.zeros((1, 2))
        state = {"rec": np.empty((4096, sk.NREC))}

        def upd(t, xs, u, params):
            y = np.zeros(self.ny)
            y[idx] = np.asarray(xs, float) * S
            if not np.all(np.isfinite(y)):
                raise ValueError(f"state at t = {t:g} s: must be finite (X0 given in the system's scaled states: "
                                 f"sys.scaled_state(...))")
            if not (-1e-9 * self.x_e <= y[sk.X] <= self.x_e * (1 + 1e-9)):
                raise ValueError(f"state at t = {t:g} s: stroke x = {y[sk.X]:g} m outside [0, x_e = {self.x_e:g}] m "
                                 f"(X0 is in the system's scaled states: sys.scaled_state(...))")
            V, F = float(u[0]), float(u[1])
            if not (math.isfinite(V) and math.isfinite(F)):
                raise ValueError(f"inputs at t = {t:g} s: voltage {V!r} V, force {F!r} N, expected finite values")
            y[-2], y[-1] = V, F
            seg["tb"][0], seg["tb"][1] = t, t + dt
            seg["v0"][0], seg["f0"][0], seg["w2"][0] = V, F, V * V
            while True:
                status, rows, _, y_end = sk.integrate(seg["tb"], seg["v0"], seg["vs"], seg["f0"], seg["fs"],
                                                      seg["w2"], gof, y, self.tables, par, self._law, self._lawp,
                                                      sc, RTOL, dt, state["rec"], limits.MAX_STEPS)
                if status == sk.FULL and state["rec"].shape[0] < 1 << 20:
                    state["rec"] = np.empty((4 * state["rec"].shape[0], sk.NREC))
                    continue
                break
            if status != sk.OK:
                raise SurrogateError(f"sampled surrogate stopped in the sample at t = {t:g} s: status {status}")
            return y_end[idx] / S

        def out(t, xs, u, params):
            x = np.asarray(xs, float) * S
            return np.array([min(max(x[0], 0.0), self.x_e), self._eval(x[:self.n_states], u[0], u[1])[1],
                             self.capacitance(x[0])])

        def scaled_state(values=None):
            """The system's scaled state from SI values: a dict by state name, or a vector in
            state_names' order (Surrogate.equilibrium's); s_m, unless given, at the lag's
            rest (the layer on its own material: s_m = -l_z(x))."""
            y = np.zeros(len(names))
            if isinstance(values, dict):
                pos = {n: i for i, n in enumerate(names)}
                for k, v in values.items():
                    if k not in pos:
                        raise ValueError(f"scaled_state: unknown state {k!r}; the states are {', '.join(names)}")
                    y[pos[k]] = float(v)
                given = set(values)
            elif values is not None:
                v = np.asarray(values, float).ravel()
                if v.size not in (self.n_states, len(names)):
                    raise ValueError(f"scaled_state: expected {self.n_states} values (state_names) or {len(names)}, "
                                     f"got {v.size}")
                y[:v.size] = v
                given = set(names[:v.size])
            else:
                given = set()
            if lag and "s_m" not in given:
                y[-1] = -float(np.interp(min(max(y[0], 0.0), self.x_e), self.x_grid, self.tables[:, sk.LZ]))
            return y / S

        sys_ = control.nlsys(upd, out, inputs=["voltage", "force"], outputs=list(self.OUTPUTS), states=names,
                             dt=dt, name=name or f"dfa_{self.family}_sampled")
        sys_.scaled_state = scaled_state
        sys_.units = dict(self.OUTPUT_UNITS)
        sys_.state_units = units
        sys_.state_scale = dict(zip(names, S.tolist()))
        return sys_

    def equilibrium(self, V, F, charges=None):
        """The stroke at rest under DC V and load F with the charges held (`charges`: {name:
        value}, default uncharged): the state vector (by state_names, SI) where the
        mechanics balance, the stroke within [0, x_e]. Zips from x = 0 (the first balance),
        like dfa_model.physics.statics.equilibrium_stroke."""
        charges = dict(charges or {})
        unknown = set(charges) - set(self.state_names)
        if unknown:
            raise ValueError(f"charges: unknown state {sorted(unknown)[0]!r}; this surrogate's states are "
                             f"{', '.join(self.state_names)}")
        base = {name: 0.0 for name in self.state_names}
        base.update(charges)
        if self.series:
            base["V_d"] = V
        xs = np.linspace(0.0, self.x_e, 401)
        x_eq = self.x_e
        vals = np.array([self._net_force(x, V, F, base) for x in xs])
        if vals[0] <= 0:
            x_eq = 0.0
        else:
            idx = np.nonzero(vals <= 0)[0]
            if len(idx):
                a, b = xs[idx[0] - 1], xs[idx[0]]
                while b - a > 1e-14 + 1e-12 * a:
                    m = 0.5 * (a + b)
                    if self._net_force(m, V, F, base) > 0:
                        a = m
                    else:
                        b = m
                x_eq = 0.5 * (a + b)
        base["x"] = x_eq
        if self.has_mass:
            base["v"] = 0.0
        return np.array([base[n] for n in self.state_names])

    def _net_force(self, x, V, F, states) -> float:
        """Electrostatic force less the load and the spring at stroke x, the other states
        as given (N)."""
        y = np.zeros(self.ny)
        for name, i in self._names:
            y[i] = states.get(name, 0.0)
        y[sk.X] = x
        y[-2], y[-1] = V, F
        ydot = np.zeros(self.ny)
        Fe, _ = sk.evaluate(y, V * V, 0.0, self.tables, self.par(lag=False), self._law, self._lawp, ydot,
                             sk.FREE)
        return float(Fe - F - self.params.k * x)

    def linearize(self, V, F, charges=None, freeze_charge=False):
        """control.StateSpace of the surrogate linearized at the stroke where the
        mechanics balance under (V, F) with the charges held (`charges`, default
        uncharged), in SI state coordinates, with the signal and state names (lin['stroke',
        'voltage'] works) and `units`. That is an equilibrium of the mechanics only: the
        charges keep drifting (their slow poles are in A), and a DC voltage's true
        equilibrium is the fully charged, unzipped actuator. `freeze_charge=True` keeps
        only the mechanical states (and V_d): the quasi-static plant a stroke controller
        sees between mechanics (ms) and charge (tens of s), whose DC gain is dx/dV and
        dx/dF at fixed charge. Differenced on the scaled system (a step of 1e-6 in each
        state is then a small step for all of them). A degenerate point (the stroke on a
        stop, or no voltage gain) gives a PhysicsWarning, not a silent zero."""
        import control
        from dfa_model import PhysicsWarning
        xs = self.equilibrium(V, F, charges)
        sysc = self.system()
        S = np.array([sysc.state_scale[n] for n in self.state_names])
        lin = control.linearize(sysc, xs / S, [V, F])
        A = lin.A * S[:, None] / S[None, :]
        B = lin.B * S[:, None]
        C = lin.C / S[None, :]
        keep = list(range(len(S))) if not freeze_charge else \
            [i for i, n in enumerate(self.state_names) if n in ("x", "v", "V_d")]
        out = control.ss(A[np.ix_(keep, keep)], B[keep, :], C[:, keep], lin.D, inputs=["voltage", "force"],
                         outputs=list(self.OUTPUTS), states=[self.state_names[i] for i in keep],
                         name=f"{sysc.name}_lin" + ("_mech" if freeze_charge else ""))
        out.units = dict(self.OUTPUT_UNITS)
        units = self.state_units()
        out.state_units = {self.state_names[i]: units[self.state_names[i]] for i in keep}
        x_eq = float(xs[0])
        if x_eq <= 0.0 or x_eq >= self.x_e:
            where = "x = 0 (unzipped)" if x_eq <= 0.0 else f"the end stop x_e = {self.x_e:g} m"
            warnings.warn(f"linearize: under {V:g} V and {F:g} N the stroke rests on {where}; the stop holds it, "
                          f"so the stroke's gains there are zero (a degenerate linearization)", PhysicsWarning,
                          stacklevel=2)
        elif abs(B[0, 0]) == 0.0 and (not self.has_mass or abs(B[self.state_names.index("v"), 0]) == 0.0):
            warnings.warn(f"linearize: no voltage gain at x = {x_eq:g} m (V = {V:g} V): a degenerate linearization",
                          PhysicsWarning, stacklevel=2)
        return out

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "family": self.family, "params_toml": self.params.to_toml(),
                "x_grid": self.x_grid.tolist(), "tables": self.tables.tolist(), "n_points": self.n_points,
                "c_ell": self.c_ell if np.isfinite(self.c_ell) else None, "c_w": self.c_w, "c_m": self.c_m,
                "c_adv": self.c_adv,
                "states": self.state_names,
                "info": self.info}

    def save(self, path) -> None:
        """Write the surrogate as JSON (loads back with reduced.load)."""
        from dfa_model.io.fileio import write_text_atomic
        write_text_atomic(path, json.dumps(self.to_dict()))

    def __repr__(self):
        return f"<Surrogate {self.family}: {self.n_states} states {self.state_names}, layout {self.params.layout}>"
