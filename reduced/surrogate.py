"""A surrogate: a few states, tabulated maps of the stroke, a fast path and python-control.

All families share one structure (the states are named in `state_names`):

    x      stroke (m)                           b dx/dt = F_e - F - k x   (m = 0)
    v      stroke velocity (m/s), only if m > 0 m dv/dt = F_e - F - k x - b v
    q_z    interface charge of zipped material (C/m^2)    dq_z/dt = a(x) q_z + b(x) V
    q_d    front-layer charge deficit q_z - q_f (C/m^2), only if the front layer's
           rates differ from zipped material's: the front layer's charge q_f follows
           dq_f/dt = a_f(x) q_f + b_f(x) V + |dl_z/dt| / ell(x) (q_f* - q_f)
           (its own rates, renewed as the front moves over ell(x) = c_ell w_f(x), w_f
           the layer's width, with the charge q_f* of the material it moves onto), so
           dq_d/dt = (a - a_f) q_z + a_f q_d + (b - b_f) V - |dl_z/dt| / ell(x) (q_d - q_d*)
           with q_d* = q_z - q_f* = 0 retreating (zipped material) and
           beta_f (1 - b_f/b) q_z advancing (the material beyond the front keeps a share
           beta_f of the deficit of a layer charged at its own rates: a front that comes
           back finds part of its layer)
    F_e    = c0(x) V^2 + c1(x) V (q_z - q_d) + c2(x) (q_z - q_d)^2
    current = i0(x) V + i1(x) q_z + dx/dt (j0(x) V + j1(x) q_z)   (no capacitive spike at a jump)

with stops at x = 0 and x = x_e. The families differ in where the maps come from (see
families.py). Inputs `voltage`, `force`; outputs `stroke`, `current`.
"""
from __future__ import annotations

import json
import time
from functools import cached_property

import numpy as np

from dfa_model import limits
from dfa_model.parameters import Parameters
from dfa_model.results import StrokeMetrics
from dfa_model.solver import protocol_load
from dfa_model.trace import StrokeTrace
from dfa_model.waveforms import DC, Bipolar, Load, Protocol, Unipolar, merge

from . import kernel
from .kernel import A_F, A_Q, B_F, B_V, NTAB, NY, P_AVG, P_B, P_BETA, P_CELL, P_FRONT, P_K, P_M, P_XE, W_F

FORMAT = "dfa-surrogate"
VERSION = 3     # 3: front-layer width w_f column, renewal (c_ell, beta_f) (2: one length ell; 1: kappa)
_PURE_WAVEFORMS = (DC, Bipolar, Unipolar)   # segments a function of their fields and the stage duration
_SEG_CACHE = 20_000                         # largest protocol (segments) whose inputs are kept


class SurrogateError(RuntimeError):
    """The surrogate's integration stopped early."""


class SurrogateResult(StrokeMetrics):
    """Time series of a surrogate run (every accepted step) and the full model's metrics
    (StrokeMetrics: unzipping speed, static stroke, ripple, drift...). `y_end`: the final
    kernel state [x, v, q_z, q_d, V, F] (to continue from, as y0)."""

    def __init__(self, surrogate, protocol, rec, wall_time, steps, y_end, load=None):
        self.surrogate = surrogate
        self.params = surrogate.params
        self.load = load if load is not None else Load(0.0)
        self.protocol = protocol
        self.rec = rec
        self.wall_time = wall_time
        self.n_steps = steps
        self.y_end = y_end
        R = kernel
        self.t, self.x, self.v = rec[:, R.R_T], rec[:, R.R_X], rec[:, R.R_V]
        self.q_z, self.q_d = rec[:, R.R_Z1], rec[:, R.R_Z2]
        self.V, self.F, self.I, self.Fe = rec[:, R.R_VOLT], rec[:, R.R_F], rec[:, R.R_I], rec[:, R.R_FE]

    @cached_property
    def trace(self) -> StrokeTrace:
        """The stroke joined linearly between the recorded steps (built on first use)."""
        return StrokeTrace.from_samples(self.t, self.x)

    def summary(self) -> dict:
        return {"static_stroke": self.static_stroke, "final_stroke": self.final_stroke,
                "unzipping_speed": self.unzipping_speed, "wall_time": self.wall_time, "steps": self.n_steps}


class Surrogate:
    """A fitted low-order model of one actuator (see the module docstring).

    family   'lumped' or 'charge'
    params   the actuator (dfa_model Parameters) the maps were computed for
    x_grid, tables  the maps of the stroke (kernel.py columns)
    c_ell    the front renews its layer as it moves by ell(x) = c_ell w_f(x) (w_f: the
             layer's width, a table column)
    beta_f   the share of a layer's deficit the material beyond the front keeps (what an
             advancing front renews the layer with)
    info     provenance: how the maps were built and fitted, training errors
    """

    def __init__(self, family, params: Parameters, x_grid, tables, c_ell=1.0, beta_f=1.0, info=None):
        self.family = family
        self.params = params
        self.x_grid = np.ascontiguousarray(x_grid, dtype=float)
        self.tables = np.ascontiguousarray(tables, dtype=float)
        if self.tables.shape != (len(self.x_grid), NTAB):
            raise ValueError(f"tables: expected shape ({len(self.x_grid)}, {NTAB}), got {self.tables.shape}")
        self.x_e = float(self.x_grid[-1])
        self.c_ell, self.beta_f = float(c_ell), float(beta_f)
        self.info = dict(info or {})
        t = self.tables      # a front layer with rates of its own makes q_d a state
        self._front = bool(np.any(t[:, A_F] != t[:, A_Q]) or np.any(t[:, B_F] != t[:, B_V]))
        self._inputs = {}       # merged input segments of recent protocols (_segments)

    # ------------------------------------------------------------------ structure
    @property
    def has_mass(self) -> bool:
        return self.params.m > 0

    @property
    def has_deficit(self) -> bool:
        return self._front

    @property
    def state_names(self) -> list[str]:
        return ["x"] + (["v"] if self.has_mass else []) + ["q_z"] + (["q_d"] if self.has_deficit else [])

    @property
    def n_states(self) -> int:
        return len(self.state_names)

    def _index(self):
        """Positions of the named states in the kernel's 6-vector [x, v, z1, z2, V, F]."""
        return [{"x": 0, "v": 1, "q_z": 2, "q_d": 3}[n] for n in self.state_names]

    def par(self, averaged=False, k_extra=0.0) -> np.ndarray:
        p = self.params
        out = np.zeros(kernel.NPAR)
        out[P_XE], out[P_B], out[P_M], out[P_K] = self.x_e, p.b, p.m, p.k + k_extra
        out[P_FRONT], out[P_AVG] = float(self.has_deficit), 1.0 if averaged else 0.0
        out[P_CELL], out[P_BETA] = self.c_ell, self.beta_f
        return out

    def q_scale(self) -> float:
        p = self.params
        return p.eps_l * 1000.0 / (p.t_lz + 2.0 * p.eps_l * p.t_f / p.eps_f)

    def scales(self) -> np.ndarray:
        qs = self.q_scale() * 10.0
        return np.array([self.x_e, self.x_e * 100.0, qs, qs, 1.0, 1.0])

    # ------------------------------------------------------------------ fast path
    def simulate(self, protocol, load=None, duration=None, *, rtol=1e-4, y0=None, max_steps=limits.MAX_STEPS,
                 averaged=None) -> SurrogateResult:
        """Run a protocol on the compiled path (kernel.py). `protocol` and `load` as in
        dfa_model.simulate. `y0`: initial state by name ({'x': ..., 'q_z': ...}) or a
        6-vector; default uncharged at rest at x = 0. `averaged`: (mean V, mean V^2) per
        segment for the cycle-averaged form (averaged.py), else None."""
        if not isinstance(protocol, Protocol):
            if duration is None:
                raise ValueError("duration: required when the protocol is a plain voltage or waveform")
            protocol = Protocol.dc(protocol, duration) if isinstance(protocol, (int, float)) else \
                Protocol.single(protocol, duration)
        load = protocol_load(protocol, load)
        if not (isinstance(rtol, (int, float)) and 1e-10 <= rtol <= 0.1):
            raise ValueError(f"rtol: got {rtol!r}, expected a number in [1e-10, 0.1]")
        t0 = time.perf_counter()
        tb, v0, vs, f0, fs = self._segments(protocol, load)
        w2 = v0 * v0 if averaged is None else np.asarray(averaged, float)
        rec, steps, y_end = self._run(tb, v0, vs, f0, fs, w2, self._y0(y0), rtol, max_steps, averaged is not None,
                                      load.k_load)
        return SurrogateResult(self, protocol, rec, time.perf_counter() - t0, steps, y_end, load)

    def _segments(self, protocol, load):
        """merge(protocol, load): the kernel's input segments. Building them costs about
        as much as a short run, so those of recent protocols are kept, keyed on the text
        of every field they depend on (a mutated protocol gets a new key). Only for the
        stock waveforms (segments a function of their fields and durations alone), a
        constant load and at most _SEG_CACHE segments; the kernel only reads them."""
        key = None
        if type(protocol) is Protocol and type(load) is Load and type(load.F) is float and \
                all(type(st.waveform) in _PURE_WAVEFORMS for st in protocol.stages):
            key = repr((load.F, [(type(st.waveform), vars(st.waveform), st.duration) for st in protocol.stages]))
            seg = self._inputs.get(key)
            if seg is not None:
                return seg
        seg = merge(protocol.piecewise(), load.piecewise(protocol.duration))
        if key is not None and len(seg[1]) <= _SEG_CACHE:
            if len(self._inputs) >= 16:
                self._inputs.clear()
            self._inputs[key] = seg
        return seg

    def _y0(self, y0):
        y = np.zeros(NY)
        if y0 is None:
            return y
        if isinstance(y0, dict):
            pos = {"x": 0, "v": 1, "q_z": 2, "q_d": 3}
            for k, v in y0.items():
                if k not in pos:
                    raise ValueError(f"y0: unknown state {k!r}; states are {', '.join(pos)}")
                y[pos[k]] = float(v)
        else:
            y[:] = np.asarray(y0, float)[:NY]
        if not np.all(np.isfinite(y)):
            raise ValueError("y0: must be finite")
        if not (0.0 <= y[0] <= self.x_e):
            raise ValueError(f"y0: stroke x = {y[0]:g} m outside [0, x_e = {self.x_e:g}] m")
        return y

    def _run(self, tb, v0, vs, f0, fs, w2, y, rtol, max_steps, averaged, k_extra=0.0):
        par = self.par(averaged, k_extra)
        cap = min(64 + 40 * len(v0), 4_000_000)
        h0 = min(1e-4, float(tb[-1] - tb[0]))
        while True:
            rec = np.empty((cap, kernel.NREC))
            status, rows, steps, y_end = kernel.integrate(tb, v0, vs, f0, fs, w2, y, self.tables, par,
                                                          self.scales(), rtol, h0, rec, max_steps)
            if status == kernel.FULL and cap < 16_000_000:
                cap *= 4
                continue
            break
        if status != kernel.OK:
            why = {kernel.FULL: "the output buffer is full", kernel.MAX_STEPS: f"the step limit ({max_steps}) was reached",
                   kernel.NONFINITE: "the solution became non-finite"}[status]
            raise SurrogateError(f"surrogate integration stopped at t = {rec[rows - 1, 0]:g} s: {why}")
        return rec[:rows].copy(), steps, y_end

    # ------------------------------------------------------------------ python-control
    def _eval(self, xs, V, F, W=None):
        y = np.zeros(NY)
        y[self._index()] = xs
        y[4], y[5] = V, F
        ydot = np.zeros(NY)
        Fe, I = kernel.evaluate(y, V * V if W is None else W, self.tables, self.par(), ydot, np.empty(NTAB),
                                kernel.AUTO)
        return ydot[self._index()], I

    def system(self, name=None):
        """This surrogate as a control.NonlinearIOSystem (inputs voltage, force; outputs
        stroke, current; states `state_names`)."""
        import control

        def upd(t, xs, u, params):
            return self._eval(xs, u[0], u[1])[0]

        def out(t, xs, u, params):
            return np.array([min(max(xs[0], 0.0), self.x_e), self._eval(xs, u[0], u[1])[1]])

        return control.nlsys(upd, out, inputs=["voltage", "force"], outputs=["stroke", "current"],
                             states=self.state_names, name=name or f"dfa_{self.family}")

    def equilibrium(self, V, F, q_z=0.0, q_d=0.0):
        """The stroke at rest under DC V and load F with the charges held at (q_z, q_d):
        the state vector (by state_names) where the mechanics balance. Zips from x = 0
        (the first balance), like dfa_model.statics.equilibrium_stroke."""
        par, ydot, rw = self.par(), np.empty(NY), np.empty(NTAB)

        def net(x):
            y = np.array([x, 0.0, q_z, q_d, V, F])
            Fe, _ = kernel.evaluate(y, V * V, self.tables, par, ydot, rw, kernel.FREE)
            return Fe - F - self.params.k * x
        xs = np.linspace(0.0, self.x_e, 401)
        vals = np.array([net(x) for x in xs])
        x_eq = self.x_e
        if vals[0] <= 0:
            x_eq = 0.0
        else:
            idx = np.nonzero(vals <= 0)[0]
            if len(idx):
                from scipy.optimize import brentq
                i = idx[0]
                x_eq = brentq(net, xs[i - 1], xs[i], xtol=1e-14)
        st = {"x": x_eq, "v": 0.0, "q_z": q_z, "q_d": q_d}
        return np.array([st[n] for n in self.state_names])

    def linearize(self, V, F, q_z=0.0, q_d=0.0, freeze_charge=False):
        """control.StateSpace of the surrogate linearized at the stroke where the
        mechanics balance under (V, F) with the charges (q_z, q_d). That is an
        equilibrium of the mechanics only: the charges keep drifting (their slow poles
        are in A), and a DC voltage's true equilibrium is the fully charged, unzipped
        actuator. `freeze_charge=True` keeps only the mechanical states: the
        quasi-static plant a stroke controller sees between mechanics (ms) and charge
        (tens of s), whose DC gain is dx/dV and dx/dF at fixed charge."""
        import control
        xs = self.equilibrium(V, F, q_z, q_d)
        lin = control.linearize(self.system(), xs, [V, F])
        if not freeze_charge:
            return lin
        keep = [i for i, n in enumerate(self.state_names) if n in ("x", "v")]
        return control.ss(lin.A[np.ix_(keep, keep)], lin.B[keep, :], lin.C[:, keep], lin.D,
                          inputs=["voltage", "force"], outputs=["stroke", "current"],
                          states=[self.state_names[i] for i in keep], name=f"{lin.name}_mech")

    # ------------------------------------------------------------------ files
    def to_dict(self) -> dict:
        return {"format": FORMAT, "version": VERSION, "family": self.family, "params_toml": self.params.to_toml(),
                "x_grid": self.x_grid.tolist(), "tables": self.tables.tolist(),
                "c_ell": self.c_ell, "beta_f": self.beta_f,
                "states": self.state_names, "info": self.info}

    def save(self, path) -> None:
        """Write the surrogate as JSON (loads back with reduced.load)."""
        from dfa_model.fileio import write_text_atomic
        write_text_atomic(path, json.dumps(self.to_dict()))

    def __repr__(self):
        return f"<Surrogate {self.family}: {self.n_states} states {self.state_names}, layout {self.params.layout}>"


def from_dict(d: dict) -> Surrogate:
    import tomllib

    from dfa_model.parameters import from_dict as params_from_dict
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise ValueError(f"not a surrogate file (expected \"format\": \"{FORMAT}\")")
    if d.get("version") != VERSION:
        raise ValueError(f"surrogate file version {d.get('version')!r}; this toolkit reads version {VERSION}")
    try:
        params = params_from_dict(tomllib.loads(d["params_toml"]), "surrogate file")
        s = Surrogate(d["family"], params, d["x_grid"], d["tables"], d["c_ell"], d["beta_f"],
                      d.get("info"))
    except KeyError as exc:
        raise ValueError(f"surrogate file: missing key {exc.args[0]!r}") from None
    if not (np.all(np.isfinite(s.tables)) and np.all(np.diff(s.x_grid) > 0) and s.c_ell > 0
            and 0.0 <= s.beta_f <= 1.0 and np.all(s.tables[:, W_F] > 0)):
        raise ValueError("surrogate file: tables, grid or deficit parameters are corrupt")
    return s


def load(path) -> Surrogate:
    """Read a surrogate written by Surrogate.save / `dfa reduce`."""
    try:
        with open(path) as fh:
            d = json.load(fh)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read ({exc.strerror})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: not JSON ({exc.msg} at line {exc.lineno})") from None
    return from_dict(d)
