"""The actuator + drive electronics + load co-simulation as an SSP file (System Structure
and Parameterization 1.0, Modelica Association): `dfa fmu build --system --out FILE.ssp`.

The archive holds SystemStructure.ssd and the three FMUs under resources/, wired as in
fmu/cosim.py:

    drive.voltage         -> actuator.voltage
    actuator.capacitance  -> drive.load_capacitance   (the drive's current limit)
    actuator.stroke       -> load.stroke
    load.force            -> actuator.force

Any SSP master runs it: fmpy.ssp.simulate.simulate_ssp, OMSimulator. The FMUs carry
their start values (the actuator's parameters from the preset or file it was built
from; the drive's reset_dc mode, 30 Hz, 3 s reset; the 0.51 kg load on 2 kN/m), and the
SSD's DefaultExperiment gives the standard run: 23 s at 1 ms.
"""
from __future__ import annotations

import os
import tempfile
from pathlib import Path
from xml.etree import ElementTree as ET

from dfa_model import parameters as P

SSD = "http://ssp-standard.org/SSP1/SystemStructureDescription"
SSC = "http://ssp-standard.org/SSP1/SystemStructureCommon"
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


def build_system(params: P.Parameters | None = None, out: str | os.PathLike = "DFASystem.ssp") -> Path:
    """Build the SSP of the actuator (for `params`, default the Table 1 preset) with the
    drive and load companions; returns its path."""
    from .build import build_companion_fmu, build_fmu, output_path, write_zip
    out = output_path(out, ".ssp", " with --system")
    with tempfile.TemporaryDirectory(prefix="dfa_ssp_") as tmp:
        tmp = Path(tmp)
        files = {"actuator": build_fmu(params, tmp / COMPONENTS["actuator"][0]),
                 "drive": build_companion_fmu("drive", tmp / COMPONENTS["drive"][0]),
                 "load": build_companion_fmu("load", tmp / COMPONENTS["load"][0])}
        write_zip(out, {"SystemStructure.ssd": system_description(),
                        **{f"resources/{COMPONENTS[name][0]}": path.read_bytes() for name, path in files.items()}})
    return out


def system_description() -> bytes:
    """SystemStructure.ssd (SSP 1.0)."""
    ET.register_namespace("ssd", SSD)
    ET.register_namespace("ssc", SSC)
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
    # SI base-unit exponents of the units used
    base = {"V": dict(kg=1, m=2, s=-3, A=-1), "N": dict(kg=1, m=1, s=-2), "m": dict(m=1), "rad": dict(rad=1),
            "A": dict(A=1), "F": dict(kg=-1, m=-2, s=4, A=2)}
    us = ET.SubElement(root, f"{{{SSD}}}Units")
    for unit in units:
        u = ET.SubElement(us, f"{{{SSC}}}Unit", name=unit)
        ET.SubElement(u, f"{{{SSC}}}BaseUnit", {k: str(v) for k, v in base[unit].items()})
    ET.SubElement(root, f"{{{SSD}}}DefaultExperiment", startTime="0.0", stopTime=f"{STOP:g}")
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)
