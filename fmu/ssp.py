"""The actuator + drive electronics + load co-simulation as an SSP file (System Structure
and Parameterization 1.0, Modelica Association): `dfa fmu build --system --out FILE.ssp`.

The archive holds SystemStructure.ssd and the three FMUs under resources/, wired as in
fmu/cosim.py:

    drive.voltage         -> actuator.voltage
    actuator.capacitance  -> drive.load_capacitance   (the drive's current limit)
    actuator.stroke       -> load.stroke
    load.force            -> actuator.force

Any SSP master runs it: fmpy.ssp.simulation.simulate_ssp, OMSimulator (its Python SSP
class, and oms_importFile, the path of its command line: the SSD's vendor annotation
names OMSimulator's fixed-step master at 1 ms, which that importer needs). The FMUs carry
their start values (the actuator's parameters from the preset or file it was built
from; the drive's reset_dc mode, 30 Hz, 3 s reset; the 0.51 kg load on 2 kN/m), and the
SSD's DefaultExperiment gives the standard run: 23 s at 1 ms.

With a drive (a protocol file, `--drive DRIVE.toml`): the drive FMU plays it (mode
"protocol", its breakpoints in the drive's resources), the load FMU's mass is the
file's [load] force over g, and the DefaultExperiment stops at the protocol's end.
Start values are baked into the FMUs, because fmpy's master ignores the SSD's
parameter bindings.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from xml.etree import ElementTree as ET

import numpy as np

from dfa_model.io import parameters as P
from dfa_model.waveforms import Protocol, Sampled

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
# OMSimulator's vendor annotation (type "org.openmodelica"): its SSD importer
# (oms_importFile: the OMSimulator command line, OMEdit, the 2.x Python API) makes a
# system only from the master named in <oms:SimulationInformation> and fails without
# one ("[NewSystem] internal error"; OMSimulator issue 1318). The importer matches the
# prefixed names literally: the prefixes must be ssd, ssc and oms.
OMS = "https://raw.githubusercontent.com/OpenModelica/OMSimulator/master/schema/oms.xsd"
OMS_ANNOTATION = "org.openmodelica"
STEP = 1e-3          # the communication step the system is meant for (s)
STOP = 23.0          # the standard protocol: 3 s reset, 20 s DC hold

# component -> (FMU file in resources/, [(connector, kind, unit)])
COMPONENTS = {
    "actuator": ("DFAActuator.fmu", [
        ("voltage", "input", "V"), ("force", "input", "N"), ("stroke", "output", "m"),
        ("zipping_angle", "output", "rad"), ("electrostatic_force", "output", "N"), ("current", "output", "A"),
        ("capacitance", "output", "F")]),
    "drive": ("DriveElectronics.fmu", [
        ("load_capacitance", "input", "F"), ("voltage", "output", "V"), ("supply_current", "output", "A")]),
    "load": ("MassSpringLoad.fmu", [
        ("stroke", "input", "m"), ("force", "output", "N"), ("mass_position", "output", "m")]),
}
CONNECTIONS = [("drive", "voltage", "actuator", "voltage"), ("actuator", "capacitance", "drive", "load_capacitance"),
               ("actuator", "stroke", "load", "stroke"), ("load", "force", "actuator", "force")]


def build_system(params: P.Parameters | None = None, out: str | os.PathLike = "DFASystem.ssp",
                 drive: Protocol | None = None, drive_source: str | None = None) -> Path:
    """Build the SSP of the actuator (for `params`, default the Table 1 preset) with the
    drive and load companions; returns its path. `drive`: a protocol (a protocol file,
    `drive_source` its name for the FMU's description) the drive FMU plays, with its
    [load] as the load FMU's weight."""
    from .build import build_companion_fmu, build_fmu, output_path, write_zip
    out = output_path(out, ".ssp", " with --system")
    drive_start = drive_files = load_start = None
    if drive is not None:
        drive_start, drive_files = drive_setup(drive, drive_source)
        load_start = load_setup(drive, drive_source)
    with tempfile.TemporaryDirectory(prefix="dfa_ssp_") as tmp:
        tmp = Path(tmp)
        files = {"actuator": build_fmu(params, tmp / COMPONENTS["actuator"][0]),
                 "drive": build_companion_fmu("drive", tmp / COMPONENTS["drive"][0], drive_start, drive_files),
                 "load": build_companion_fmu("load", tmp / COMPONENTS["load"][0], load_start)}
        stop = STOP if drive is None else drive.duration
        write_zip(out, {"SystemStructure.ssd": system_description(stop),
                        **{f"resources/{COMPONENTS[name][0]}": path.read_bytes() for name, path in files.items()}})
    return out


# no step of the master shorter than this (s) meets the drive's slew-rate limit in protocol mode
SHORTEST_STEP = 1e-9


def drive_setup(drive: Protocol, source: str | None = None) -> tuple[dict, dict]:
    """The drive FMU's start values and resources that make it play `drive`: its
    breakpoints (Protocol.piecewise: t, v0, slope) and duration in
    resources/drive_protocol.json (JSON floats are exact), mode = "protocol"."""
    import json

    from .drive_electronics import PROTOCOL_FILE, PROTOCOL_MODE
    pw = drive.piecewise()
    t, v0, slope = (np.asarray(a, float) for a in (pw.t, pw.v0, pw.slope))
    ends = v0 + slope * np.diff(t)
    # The protocol already holds the drive's ramps (a designed drive's slew_rate), and may
    # switch in jumps: the amplifier's limits must not reshape it. slew_rate starts where
    # no master step of 1 ns or longer can meet it: the protocol's whole swing (0 V, the
    # output before the first step, included) in 1 ns, and at least its steepest ramp.
    # current_limit starts at that rate into 1 F, so that I / C binds on no load below
    # 1 F (an actuator is ~1 nF). Both stay parameters a host may set to a real
    # amplifier's limits.
    swing = max(0.0, v0.max(), ends.max()) - min(0.0, v0.min(), ends.min())
    slew = max(swing / SHORTEST_STEP, float(np.abs(slope).max()), 1.0)
    data = {"source": source or "protocol", "duration": float(drive.duration), "t": t.tolist(), "v0": v0.tolist(),
            "slope": slope.tolist()}
    start = {"mode": PROTOCOL_MODE, "slew_rate": slew, "current_limit": slew * 1.0}     # A: slew into 1 F
    return start, {PROTOCOL_FILE: json.dumps(data).encode()}


def load_setup(drive: Protocol, source: str | None = None) -> dict | None:
    """The load FMU's start values for the protocol's [load]: a constant force F > 0
    hangs a mass F / g (the mass-spring's rest force m g = F); None without a [load]
    (the default 0.51 kg). What a hanging mass cannot be is a BuildError naming the
    protocol file (`source`) and [load]."""
    from .build import BuildError
    from .mass_spring_load import G
    load = drive.load
    if load is None:
        return None
    where = f"{source}: [load]" if source else "[load]"
    what = "the system's load FMU is a mass hanging on a spring (rest force m g)"
    if load.k_load != 0:
        raise BuildError(f"{where}: k_load = {load.k_load:g} N/m: {what}, it has no load spring; remove k_load "
                         f"(dfa simulate --protocol plays it)")
    if isinstance(load.F, Sampled) or callable(load.F):
        raise BuildError(f"{where}: a sampled force: {what}, a constant weight; expected a constant force "
                         f"(dfa simulate --protocol plays it)")
    F = float(load.F)
    if not F > 0:
        raise BuildError(f"{where}: force = {F:g} N: {what}, its weight is > 0; expected force > 0, or no [load] "
                         f"for the default 0.51 kg")
    return {"mass": F / G}


def system_description(stop: float = STOP) -> bytes:
    """SystemStructure.ssd (SSP 1.0); its DefaultExperiment runs 0 to `stop` s."""
    from .units import BASE, base_unit
    ET.register_namespace("ssd", SSD)
    ET.register_namespace("ssc", SSC)
    ET.register_namespace("oms", OMS)
    root = ET.Element(f"{{{SSD}}}SystemStructureDescription", version="1.0", name="DFASystem")
    system = ET.SubElement(root, f"{{{SSD}}}System", name="DFASystem",
                           description="Dielectric fluid actuator driven by a high-voltage amplifier, lifting a "
                                       "mass on a spring")
    elements = ET.SubElement(system, f"{{{SSD}}}Elements")
    units = {}
    for name, (fmu, connectors) in COMPONENTS.items():
        comp = ET.SubElement(elements, f"{{{SSD}}}Component", name=name, type="application/x-fmu-sharedlibrary",
                             source=f"resources/{fmu}")
        conns = ET.SubElement(comp, f"{{{SSD}}}Connectors")
        for cname, kind, unit in connectors:
            c = ET.SubElement(conns, f"{{{SSD}}}Connector", name=cname, kind=kind)
            ET.SubElement(c, f"{{{SSC}}}Real", unit=unit)
            units[unit] = None
    connections = ET.SubElement(system, f"{{{SSD}}}Connections")
    for a, ca, b, cb in CONNECTIONS:
        ET.SubElement(connections, f"{{{SSD}}}Connection", startElement=a, startConnector=ca, endElement=b,
                      endConnector=cb)
    # OMSimulator's master for the system: fixed steps of STEP (the System's last child)
    annotation = ET.SubElement(ET.SubElement(system, f"{{{SSD}}}Annotations"), f"{{{SSC}}}Annotation",
                               type=OMS_ANNOTATION)
    info = ET.SubElement(ET.SubElement(annotation, f"{{{OMS}}}Annotations"), f"{{{OMS}}}SimulationInformation")
    ET.SubElement(info, f"{{{OMS}}}FixedStepMaster", description="oms-ma", stepSize=f"{STEP:g}",
                  relativeTolerance="0.0001")
    # SI base-unit exponents of the units used (fmu/units.py, as in the FMUs)
    us = ET.SubElement(root, f"{{{SSD}}}Units")
    for unit in units:
        factor, dims = base_unit(unit)
        u = ET.SubElement(us, f"{{{SSC}}}Unit", name=unit)
        ET.SubElement(u, f"{{{SSC}}}BaseUnit", {k: str(dims[k]) for k in BASE if k in dims}
                      | ({} if factor == 1.0 else {"factor": f"{factor:.16g}"}))
    text = f"{stop:g}"
    experiment = ET.SubElement(root, f"{{{SSD}}}DefaultExperiment", startTime="0.0",
                               stopTime=text if float(text) == stop else repr(float(stop)))
    # OMSimulator's result settings, its own defaults: without them its importer warns of
    # "wrong/deprecated content"
    annotation = ET.SubElement(ET.SubElement(experiment, f"{{{SSD}}}Annotations"), f"{{{SSC}}}Annotation",
                               type=OMS_ANNOTATION)
    ET.SubElement(ET.SubElement(annotation, f"{{{OMS}}}Annotations"), f"{{{OMS}}}SimulationInformation",
                  resultFile="DFASystem_res.mat", loggingInterval="0", bufferSize="10")
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
