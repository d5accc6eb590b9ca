"""The result of a simulation: arrays, metrics, energy balance, CSV export, plots."""
from __future__ import annotations

import csv
import io
import json

import numpy as np

from .. import metrics
from ..physics.equations import (R_ANG, R_C, R_EDAMP, R_EIMPACT, R_EIN, R_EINTRA, R_EJ, R_ELOAD, R_EMAX, R_ESRC, R_F, R_FE,
                        R_I, R_LZ, R_Q, R_T, R_U, R_V, R_VOLT, R_X)
from .fileio import write_text_atomic
from ..numerics.trace import StrokeTrace

# what the zipping_angle column is, per layout (the CSV header says it)
ZIPPING_ANGLE = {
    "v-shaped": "theta = 2 asin(a / (l - l_z)), the opening angle between the films at the front (Eq. 18)",
    "peano-hasel": "theta, half the curvature angle of the bulged pouch's arcs (Appendix A, Eqs. 22-24; "
                   "theta_0 at x = 0), not an angle at the front",
}
CSV_COLUMNS = ["time", "voltage", "force", "stroke", "current", "velocity", "zipped_length",
               "zipping_angle", "electrostatic_force", "capacitance", "stored_energy"]


class StrokeMetrics:
    """The metrics of a stroke record over a protocol, shared by the full model's
    Result and the surrogates' results: needs `protocol` and `trace`."""

    # ---------------------------------------------------------------- windows
    def stage(self, label):
        return self.protocol.stage_span(label)

    @property
    def has_reset(self):
        return self.stage("reset") is not None

    def hold_window(self):
        """(t0, t1) of the unzipping window (see metrics.unzipping_speed)."""
        span = self.stage("hold")
        if self.has_reset and span is not None:
            return span
        t0 = span[0] if span is not None else 0.0
        return self.trace.argmax(t0, self.trace.t1), self.trace.t1

    # ---------------------------------------------------------------- metrics
    @property
    def unzipping_speed(self) -> float:
        t0, t1 = self.hold_window()
        return metrics.unzipping_speed(self.trace, t0, t1)

    @property
    def static_stroke(self) -> float:
        """Mean stroke over the reset stage (the paper's experimental definition), or
        over the first 0.5 s when there is no reset."""
        span = self.stage("reset")
        t0, t1 = span if span is not None else (0.0, min(0.5, self.trace.t1))
        return metrics.time_mean(self.trace, t0, t1)

    @property
    def final_stroke(self) -> float:
        return float(self.trace(self.trace.t1))

    @property
    def peak_stroke(self) -> float:
        """Largest stroke over the run (m)."""
        return self.trace.max()

    def _window(self, label):
        span = self.stage(label) if label is not None else None
        return span if span is not None else (self.trace.t0, self.trace.t1)

    # ------------------------------------------------- words with one meaning
    @property
    def period(self) -> float | None:
        """Period of the last stage's square wave (s), None if it is not periodic."""
        return getattr(self.protocol.stages[-1].waveform, "period", None)

    def _period(self, period, name):
        period = self.period if period is None else period
        if period is None:
            raise ValueError(f"{name}: the run's last stage is not periodic; give the period (s)")
        return period

    @property
    def x_static(self) -> float:
        """The uncharged static stroke (m) at the last stage's amplitude and the load at the
        end (statics.equilibrium_stroke): what the stroke would be without interface charge."""
        if getattr(self, "_x_static", None) is None:
            import warnings

            from ..physics.dielectrics import PhysicsWarning
            from ..physics.statics import equilibrium_stroke
            t1 = self.protocol.duration
            F = float(self.load.piecewise(t1)(t1))
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", PhysicsWarning)
                self._x_static = float(equilibrium_stroke(self.params, self.protocol.stages[-1].waveform.amplitude,
                                                          F, warn=False, k_load=self.load.k_load))
        return self._x_static

    def ripple(self, period=None, last=1) -> float:
        """Peak-to-peak stroke over one period (m): the last whole period of the run (the
        mean over the last `last` periods); period defaults to the last stage's."""
        return metrics.last_periods(self.trace, self._period(period, "ripple"), last)[0]

    @property
    def end_stroke(self) -> float:
        """The stroke the run ends at (m): the mean over the last period of a periodic last
        stage (its ripple averaged out), else the final stroke."""
        if self.period is None or self.period > self.trace.t1 - self.trace.t0:
            return self.final_stroke
        return metrics.last_periods(self.trace, self.period)[1]

    @property
    def drift(self) -> float:
        """Stroke lost over the run (m, positive when lost): x_static minus end_stroke.
        (It was a rate of the other sign, drift(period): that is drift_rate now; calling
        drift(...) fails rather than return a length where a rate was meant.)"""
        return _Length(self.x_static - self.end_stroke)

    def drift_rate(self, period=None, label="hold", skip=1) -> float:
        """Rate of stroke loss (m/s, positive when the stroke creeps down): the slope of the
        per-period mean stroke over stage `label` (the whole run if it has none), sign
        flipped; period defaults to the last stage's."""
        return metrics.drift_rate(self.trace, self._period(period, "drift_rate"), *self._window(label), skip)


class _Length(float):
    """A float that says what to call instead when called like the old drift(period)."""

    def __call__(self, *args, **kwargs):
        raise TypeError("drift is the stroke lost over the run (m, positive when lost), a number, not a method; "
                        "the rate of the per-period mean stroke is drift_rate(period) (m/s, positive when lost)")


class Result(StrokeMetrics):
    """Time series (SI units) and metrics of one run.

    Arrays: t, x (stroke), v, lz, theta (zipping angle, rad), Fe (zipping force, N),
    I (device current, A), C (capacitance at fixed interface charge, F), U (stored
    electrostatic energy, J), V, F, E_max (largest |E_l|, V/m). `states` holds the
    element states at each output when requested (`charges=True`).

    `trace` is the stroke as the solver computed it (every accepted step, see
    trace.StrokeTrace): the metrics use it, not the output samples, so they do not
    depend on `t_eval`."""

    def __init__(self, model, protocol, load, rec, states, stats, wall_time, y_end, energy=False,
                 y0=None, V_before=0.0, trace=None):
        self.model = model
        self.params = model.params
        self.protocol = protocol
        self.load = load
        self.rec = rec
        self.states = states
        self.y_end = y_end
        self.y0, self.V_before = y0, V_before
        self.wall_time = wall_time
        self.n_steps, self.n_rejected, self.n_rhs, self.n_jac = (int(v) for v in stats[:4])
        self.has_energy = energy
        self.t, self.x, self.v = rec[:, R_T], rec[:, R_X], rec[:, R_V]
        self.lz, self.theta, self.Fe = rec[:, R_LZ], rec[:, R_ANG], rec[:, R_FE]
        self.I, self.C, self.U = rec[:, R_I], rec[:, R_C], rec[:, R_U]
        self.V, self.F, self.E_max, self.Q = rec[:, R_VOLT], rec[:, R_F], rec[:, R_EMAX], rec[:, R_Q]
        if trace is not None and len(trace) >= 1:
            self.trace = StrokeTrace.from_solver(trace, 0.0, model.kin.x_e)
        else:
            self.trace = StrokeTrace.from_samples(self.t, self.x)

    def summary(self) -> dict:
        return {"static_stroke": self.static_stroke, "final_stroke": self.final_stroke,
                "unzipping_speed": self.unzipping_speed, "wall_time": self.wall_time,
                "steps": self.n_steps, "rejected_steps": self.n_rejected}

    def drive_summary(self) -> dict:
        """The words of a held stroke (README, 'Words with one meaning'): x_static,
        end_stroke and drift (m, positive when lost); for a periodic last stage also its
        period, ripple (m, the last period) and drift_rate (m/s, positive when lost, over
        that stage); input_power (W): the source's mean power over the last period (else
        the run) when energy was integrated."""
        out = {"x_static": self.x_static, "end_stroke": self.end_stroke, "drift": float(self.drift)}
        T = self.period
        if T is not None and T <= self.trace.t1 - self.trace.t0:
            out.update(period=T, ripple=self.ripple(), drift_rate=self.drift_rate(T, label=None))
        if self.has_energy:
            out["input_power"] = self.input_power()
        return out

    def input_power(self, t0=None) -> float:
        """Mean power the source delivers (W) over [t0, end], from the energy record's E_in
        (simulate(..., energy=True)): t0 defaults to the start of the last period of a
        periodic last stage (the drive's steady power), else the start. E_in is exact at the
        output times and interpolated linearly between them (sample t0 with t_eval for an
        exact figure)."""
        if not self.has_energy:
            raise ValueError("input_power: run simulate(..., energy=True)")
        t1 = float(self.t[-1])
        if t0 is None:
            T = self.period
            t0 = t1 - T if T is not None and T < t1 - self.t[0] else float(self.t[0])
        if not t1 > t0:
            return 0.0
        e0 = float(np.interp(t0, self.t, self.rec[:, R_EIN]))
        return float((self.rec[-1, R_EIN] - e0) / (t1 - t0))

    # ---------------------------------------------------------------- energy
    def energy_balance(self) -> dict:
        """Cumulative energy terms over the run (J) and the relative residual of
        E_in = dU_e + dKE + Joule + intra-element + source + damping + load work + impacts.
        'intra' is the redistribution loss of the continuum scheme's uniform-q elements
        (>= 0, vanishing as N grows); 'source' the loss of ideal voltage steps (or of the
        fictitious series resistor in the paper scheme); 'impact' the kinetic energy lost
        when a moving mass hits a stop (inelastic)."""
        if not self.has_energy:
            raise ValueError("energy_balance: run simulate(..., energy=True)")
        r0, r1 = self.rec[0], self.rec[-1]
        m = self.params.m
        dKE = 0.5 * m * (r1[R_V] ** 2 - r0[R_V] ** 2)
        # from the state just before t = 0: a voltage jump there is booked in E_in and source
        U0 = self.model.diagnostics(self.y0, self.V_before)[0][R_U]
        terms = {"E_in": r1[R_EIN], "dU": r1[R_U] - U0, "dKE": dKE, "joule": r1[R_EJ],
                 "intra": r1[R_EINTRA], "source": r1[R_ESRC], "damping": r1[R_EDAMP], "load": r1[R_ELOAD],
                 "impact": r1[R_EIMPACT]}
        out = sum(terms[k] for k in ("dU", "dKE", "joule", "intra", "source", "damping", "load", "impact"))
        terms["residual"] = (terms["E_in"] - out) / max(abs(terms["E_in"]), 1e-300)
        return terms

    # ---------------------------------------------------------------- export
    def columns(self) -> dict:
        return {"time": self.t, "voltage": self.V, "force": self.F, "stroke": self.x, "current": self.I,
                "velocity": self.v, "zipped_length": self.lz, "zipping_angle": self.theta,
                "electrostatic_force": self.Fe, "capacitance": self.C, "stored_energy": self.U}

    def to_csv(self, path=None, comment=None) -> str | None:
        """Write the recording-format CSV (time,voltage,force,stroke,current, then the
        other outputs). Returns the text if path is None."""
        buf = io.StringIO()
        buf.write("# dfa_model simulation, SI units (s, V, N, m, A, m/s, m, rad, N, F, J)\n")
        buf.write(f"# zipping_angle: {ZIPPING_ANGLE[self.params.layout]}\n")
        if comment:
            for line in str(comment).splitlines():
                buf.write(f"# {line}\n")
        cols = self.columns()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(CSV_COLUMNS)
        data = np.column_stack([cols[c] for c in CSV_COLUMNS])
        for row in data:
            w.writerow([f"{v:.10g}" for v in row])
        text = buf.getvalue()
        if path is None:
            return text
        write_text_atomic(path, text)
        return None

    def to_json(self) -> str:
        return json.dumps(self.summary())

    def plot(self, path=None, title=None, source=None):
        """Voltage, stroke, forces and current against time (plotting.plot_result);
        `source` names where the parameters came from in the default title."""
        from .plotting import plot_result
        return plot_result(self, path, title, source)

    def front_field(self):
        """|E_l| (V/m) at the zipped material point next to the front, at each output
        (needs charges=True): the portion that dominates the unzipping (Sec. 4.3.2)."""
        if self.states is None:
            raise ValueError("front_field: run simulate(..., charges=True)")
        out = np.empty(len(self.t))
        for i in range(len(self.t)):
            s, sigma_l, _ = self.model.charges(self.states[i], self.V[i])
            zipped = np.nonzero(s <= self.lz[i])[0]
            j = zipped[-1] if zipped.size else 0
            out[i] = abs(sigma_l[j]) / self.params.eps_l
        return out

    def front_resistivity(self):
        """rho_l (ohm m) of the zipped material point next to the front (charges=True)."""
        return self.model.law.rho(self.front_field())

    def charge_profile(self, index=-1):
        """(s, sigma_l, sigma_f) along the electrode at output `index` (needs charges=True)."""
        if self.states is None:
            raise ValueError("charge_profile: run simulate(..., charges=True)")
        return self.model.charges(self.states[index], self.V[index])
