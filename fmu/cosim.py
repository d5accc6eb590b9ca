"""Co-simulation of the actuator FMU with a drive-electronics FMU and a load FMU, run
by fmpy: the wiring a user copies to put the actuator into their own system.

    drive.voltage         -> actuator.voltage
    actuator.capacitance  -> drive.load_capacitance   (the drive's current limit)
    actuator.stroke       -> load.stroke
    load.force            -> actuator.force

Fixed-step Jacobi master: every communication step, all outputs are read, then all
inputs set, then every FMU steps over [t, t + dt].

The same system ships as an SSP file (fmu/ssp.py, `dfa fmu build --system`) that any SSP
master runs; fmpy's (fmpy.ssp.simulation.simulate_ssp) gives the same stroke (tested).
This master stays for what fmpy's cannot do: set start values other than the FMUs' own,
String ones included (the drive's mode = "inversion", a reset_time: fmpy's master ignores
the SSD's parameter bindings and sets Real, Integer and Boolean only), start from the
FMUs' initial outputs (fmpy's first step sees zero inputs), and keep the communication
times exact (k dt; fmpy sums them).
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

# actuator outputs recorded, and the companions' signals
RECORD = ("stroke", "zipping_angle", "electrostatic_force", "current", "capacitance")


def _vrs(md):
    return {v.name: v.valueReference for v in md.modelVariables}


class _Unit:
    """One FMU instance through fmpy's FMU2Slave."""

    def __init__(self, path, name, start: dict, t_stop):
        import fmpy
        from fmpy.fmi2 import FMU2Slave
        self.md = fmpy.read_model_description(str(path))
        self.dir = fmpy.extract(str(path))
        self.vr = _vrs(self.md)
        self.fmu = FMU2Slave(guid=self.md.guid, unzipDirectory=self.dir,
                             modelIdentifier=self.md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0, stopTime=t_stop)
        self.fmu.enterInitializationMode()
        for key, value in start.items():
            if key not in self.vr:
                raise ValueError(f"{name}: no variable {key!r}")
            kind = next(v.type for v in self.md.modelVariables if v.name == key)
            setter = {"Real": self.fmu.setReal, "Integer": self.fmu.setInteger, "Boolean": self.fmu.setBoolean,
                      "String": self.fmu.setString}[kind]
            setter([self.vr[key]], [value])
        self.fmu.exitInitializationMode()

    def get(self, names):
        return self.fmu.getReal([self.vr[n] for n in names])

    def set(self, names, values):
        self.fmu.setReal([self.vr[n] for n in names], list(values))

    def close(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def cosimulate(actuator: str | Path, drive: str | Path, load: str | Path, stop_time: float, step: float = 1e-3, *,
               actuator_start: dict | None = None, drive_start: dict | None = None,
               load_start: dict | None = None) -> dict:
    """Run the three FMUs to stop_time with communication step `step`. Returns arrays
    't', 'voltage' (drive output), 'supply_current', 'force' (load), 'mass_position' and
    the actuator outputs in RECORD, sampled at every communication point."""
    n = int(round(stop_time / step))
    if n < 1 or abs(n * step - stop_time) > 1e-9 * stop_time:
        raise ValueError(f"stop_time: expected a positive multiple of step = {step:g} s, got {stop_time!r}")
    units = []
    try:
        act = _Unit(actuator, "actuator", actuator_start or {}, stop_time)
        units.append(act)
        drv = _Unit(drive, "drive", drive_start or {}, stop_time)
        units.append(drv)
        ld = _Unit(load, "load", load_start or {}, stop_time)
        units.append(ld)
        out = {k: np.empty(n + 1) for k in ("t", "voltage", "supply_current", "force", "mass_position", *RECORD)}
        i_cap = RECORD.index("capacitance")
        for k in range(n + 1):
            t = k * step
            a = act.get(RECORD)
            v, i_s = drv.get(("voltage", "supply_current"))
            f, xm = ld.get(("force", "mass_position"))
            out["t"][k], out["voltage"][k], out["supply_current"][k] = t, v, i_s
            out["force"][k], out["mass_position"][k] = f, xm
            for name, value in zip(RECORD, a):
                out[name][k] = value
            if k == n:
                break
            act.set(("voltage", "force"), (v, f))
            drv.set(("load_capacitance",), (a[i_cap],))
            ld.set(("stroke",), (a[0],))
            for u in units:
                u.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=step)
        return out
    finally:
        for u in units:
            u.close()
