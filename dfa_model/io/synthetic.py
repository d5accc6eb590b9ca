"""Synthetic recordings: a truth model with hidden effects, measured like a real rig.

    from dfa_model.io.synthetic import Measurement, generate_dataset
    truth = preset("vshape-table1").replace(k=300.0)          # a hidden stiffness
    generate_dataset("ds/", truth, nominal=preset("vshape-table1"),
                     conditions=[(6000, 3), (6000, 5), (8000, 5)], repetitions=3, seed=1)

Each recording is the paper's routine (Sec. 4.2): a charge reset (bipolar, 100 % duty, at
the test amplitude, `reset_frequency`) for `reset` s, then a DC hold for `hold` s (other
drives: `drive="inversion"`, a bipolar 100 % duty square wave at `reset_frequency` over
reset + hold; `drive="unipolar"`, unipolar pulses at `reset_frequency`, duty 0.5, for
`reset` s, then the DC hold), sampled
at 1 / dt, run on the full model with the truth parameters, then measured. The recorder
starts `pretrigger` s before the drive (0 V, the actuator at rest): what a rig's
pre-trigger gives, and the only stretch where the sensor's zero can be read apart from
the actuator's static stroke (without it, one sample at rest read the zero to the noise,
2 um, and a stiffness's static offset hid in those errors). The measurement:
- the repetition's liquid resistivity differs from the truth's by a factor
  exp(N(0, rho_spread)) at every field (scaled_resistivity);
- the laser sensor adds white noise of `noise` m RMS, reads relative to a zero that is off
  by N(0, offset) m per recording, and rounds to `quantum` m;
- the voltage channel adds white noise of `voltage_noise` V RMS (levels stay levels) and
  reads with a gain off by N(0, voltage_gain) per recording (the monitor's calibration);
- the force channel adds white noise of `force_noise` N RMS;
- the drive's clock is not the sampler's: each recording's reset runs at
  reset_frequency (1 + N(0, clock)), so the switches fall at every phase of the samples
  (a drive locked to the sampling grid would put every third switch of a 30 Hz reset
  exactly on a sample, a case no real rig produces).
The dataset folder gets `actuator.toml` (the *nominal* parameters: what the user knows)
and one CSV per recording, named V<kV>_F<N>_r<k>.csv; what was drawn (the per-recording
factors and offsets, the truth) is returned and, if `manifest` is given, written there -
never into the dataset (the diagnosis must not see it).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from ..physics.dielectrics import ResistivityLaw
from ..physics.model import DFAModel
from .parameters import Parameters
from ..numerics.solver import simulate
from ..waveforms import DC, Bipolar, Protocol, Stage, Unipolar


TRUTH_RTOL = 1e-7   # the truth model's integrator tolerance (at most)
DRIVES = ("reset_hold", "inversion", "unipolar")


@dataclass
class Measurement:
    noise: float = 2e-6            # sensor white noise, RMS (m)
    quantum: float = 0.5e-6        # sensor resolution (m)
    offset: float = 5e-6           # SD of the per-recording sensor zero offset (m)
    rho_spread: float = 0.03       # SD of log(rho_l) between repetitions
    voltage_noise: float = 5.0     # voltage channel noise, RMS (V)
    dt: float = 1e-3               # sample period (s)
    clock: float = 1e-3            # relative SD of the drive's reset frequency against the sampling clock
    voltage_gain: float = 0.0      # SD of the voltage monitor's relative gain error, per recording
    force_noise: float = 0.0       # force channel noise, RMS (N)

    def __post_init__(self):
        for k, v in asdict(self).items():
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"{k}: got {v!r}, expected a finite number >= 0")
        if not 1e-6 <= self.dt <= 0.1:
            raise ValueError(f"dt: got {self.dt!r}, expected a sample period in [1e-6, 0.1] s")


def scaled_resistivity(p: Parameters, factor: float) -> Parameters:
    """p with its liquid resistivity times `factor` at every field: the constant and the
    spline law's rho_l (the spline's knots are relative to it); the linear law's slope
    m_rho, intercept q_rho and floor rho_min."""
    if p.law == "linear":
        return p.replace(m_rho=p.m_rho * factor, q_rho=p.q_rho * factor, rho_min=p.rho_min * factor)
    return p.replace(rho_l=p.rho_l * factor)


class ExponentialResistivity(ResistivityLaw):
    """A truth law outside the catalog's forms: rho_l = rho_min + (rho_0 - rho_min)
    exp(-|E| / E_0) (dissociation rising with the field, down to a floor)."""

    def __init__(self, rho_0: float, E_0: float, rho_min: float = 0.0):
        self.rho_0, self.E_0, self.rho_min = float(rho_0), float(E_0), float(rho_min)

    def rho(self, E):
        return self.rho_min + (self.rho_0 - self.rho_min) * np.exp(-np.abs(np.asarray(E, float)) / self.E_0)

    def __repr__(self):
        return f"ExponentialResistivity(rho_0={self.rho_0:g}, E_0={self.E_0:g}, rho_min={self.rho_min:g})"


class PowerResistivity(ResistivityLaw):
    """A truth law outside the catalog's forms: rho_l = rho_0 (|E| / E_ref)^-n above
    E_on, rho_0 (E_on / E_ref)^-n below it (a power law from an onset field)."""

    def __init__(self, rho_0: float, E_ref: float, n: float, E_on: float):
        self.rho_0, self.E_ref, self.n, self.E_on = float(rho_0), float(E_ref), float(n), float(E_on)

    def rho(self, E):
        E = np.maximum(np.abs(np.asarray(E, float)), self.E_on)
        return self.rho_0 * (E / self.E_ref) ** -self.n

    def __repr__(self):
        return f"PowerResistivity(rho_0={self.rho_0:g}, E_ref={self.E_ref:g}, n={self.n:g}, E_on={self.E_on:g})"


class _ScaledLaw(ResistivityLaw):
    """law x factor at every field (a repetition's resistivity spread)."""

    def __init__(self, law, factor):
        self.law, self.factor = law, float(factor)

    def rho(self, E):
        return self.factor * np.asarray(self.law.rho(E), float)


def recording_name(V: float, F: float, rep: int) -> str:
    return f"V{V / 1e3:g}kV_F{F:g}N_r{rep}"


def generate_dataset(folder, truth: Parameters, nominal: Parameters | None = None, conditions=((6000.0, 5.0),),
                     repetitions: int = 3, reset: float = 3.0, hold: float = 20.0, reset_frequency: float = 30.0,
                     measurement: Measurement | None = None, seed: int = 0, manifest=None,
                     pretrigger: float = 0.1, drive: str = "reset_hold", law: ResistivityLaw | None = None) -> dict:
    """Write a dataset folder (module docstring); returns what was drawn. `law`: the
    truth's resistivity law when it is none of the parameter file's (e.g.
    ExponentialResistivity; truth's own law keys are then ignored)."""
    meas = measurement or Measurement()
    nominal = nominal or truth
    if not isinstance(repetitions, int) or repetitions < 1:
        raise ValueError(f"repetitions: got {repetitions!r}, expected an integer >= 1")
    if drive not in DRIVES:
        raise ValueError(f"drive: got {drive!r}, expected one of {', '.join(DRIVES)}")
    conditions = [(float(V), float(F)) for V, F in conditions]
    if not conditions:
        raise ValueError("conditions: at least one (voltage, force) pair")
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "actuator.toml").write_text("# nominal actuator (synthetic dataset)\n" + nominal.to_toml())
    rng = np.random.default_rng(seed)
    if not (math.isfinite(pretrigger) and 0 <= pretrigger <= 10):
        raise ValueError(f"pretrigger: got {pretrigger!r}, expected 0-10 s")
    t = np.round(np.arange(0.0, pretrigger + reset + hold + meas.dt / 2, meas.dt), 12)
    drawn = []
    for V, F in conditions:
        for rep in range(1, repetitions + 1):
            f_drive = reset_frequency * (1.0 + float(rng.normal(0.0, meas.clock)))
            # the trigger falls anywhere within a sample (a drive started on the sampling
            # grid would time the first switch exactly)
            pre = pretrigger + float(rng.uniform(0.0, meas.dt)) if pretrigger > 0 else 0.0
            stages = [Stage(DC(0.0), pre, "pretrigger")] if pre > 0 else []
            rest = t[-1] - pre - (reset if reset > 0 else 0.0)
            if drive == "inversion":
                stages.append(Stage(Bipolar(V, f_drive, 1.0), t[-1] - pre, "hold"))
            else:
                if reset > 0:
                    stages.append(Stage(Bipolar(V, f_drive, 1.0) if drive == "reset_hold" else
                                        Unipolar(V, f_drive, 0.5), reset, "reset"))
                stages.append(Stage(DC(V), rest, "hold"))
            protocol = Protocol(stages)
            factor = float(np.exp(rng.normal(0.0, meas.rho_spread)))
            offset = float(rng.normal(0.0, meas.offset))
            p = scaled_resistivity(truth, factor)
            model = p if law is None else DFAModel(truth, law=_ScaledLaw(law, factor))
            # the rig measures the physics, not our integrator's error at its tolerance
            res = simulate(model, protocol, load=F, t_eval=t, warn=False, rtol=min(p.rtol, TRUTH_RTOL))
            x = res.trace(t)
            x_meas = x + offset + rng.normal(0.0, meas.noise, t.size)
            if meas.quantum > 0:
                x_meas = np.round(x_meas / meas.quantum) * meas.quantum
            gain = 1.0 + float(rng.normal(0.0, meas.voltage_gain)) if meas.voltage_gain > 0 else 1.0
            v_meas = gain * protocol.voltage(t) + rng.normal(0.0, meas.voltage_noise, t.size)
            f_meas = np.full(t.size, F) + (rng.normal(0.0, meas.force_noise, t.size) if meas.force_noise > 0 else 0.0)
            name = recording_name(V, F, rep)
            data = np.column_stack([t, v_meas, f_meas, x_meas])
            lines = [f"# synthetic recording {name}: {pretrigger:g} s at 0 V, drive {drive} ({reset:g} s at "
                     f"{reset_frequency:g} Hz, {hold:g} s hold) at {V:g} V against {F:g} N", "time,voltage,force,stroke"]
            lines += [f"{a:.6f},{b:.6g},{c:.6g},{d:.9g}" for a, b, c, d in data]
            (folder / f"{name}.csv").write_text("\n".join(lines) + "\n")
            drawn.append({"recording": name, "voltage": V, "force": F, "repetition": rep, "pretrigger": pre,
                          "rho_factor": factor, "offset": offset, "reset_frequency": f_drive,
                          "voltage_gain": gain})
    out = {"truth": truth.to_dict(), "truth_law": repr(law) if law is not None else None, "nominal": nominal.to_dict(), "measurement": asdict(meas), "seed": seed,
           "recordings": drawn}
    if manifest is not None:
        Path(manifest).write_text(json.dumps(out, indent=1))
    return out
