"""The FMUs' units (fmu/units.py) and the SSD's OMSimulator annotation (fmu/ssp.py),
without building an FMU: Modelica spelling, SI exponents against a table written out
by hand here, display-unit factors, and the annotation's exact element names."""
import math
import re

import pytest

from dfa_model.io import parameters as P
from fmu import units as U

# SI base-unit exponents (kg, m, s, A, K, mol, cd, rad), derived by hand: the check of
# the parser, not its output
SI = {
    "1": {}, "m": dict(m=1), "m/s": dict(m=1, s=-1), "m3": dict(m=3), "kg": dict(kg=1), "s": dict(s=1),
    "A": dict(A=1), "rad": dict(rad=1), "Hz": dict(s=-1),
    "N": dict(kg=1, m=1, s=-2),                       # kg m / s2
    "N/m": dict(kg=1, s=-2),
    "N.s/m": dict(kg=1, s=-1),
    "J": dict(kg=1, m=2, s=-2),                       # N m
    "V": dict(kg=1, m=2, s=-3, A=-1),                 # W / A
    "V/m": dict(kg=1, m=1, s=-3, A=-1),
    "V/s": dict(kg=1, m=2, s=-4, A=-1),
    "F": dict(kg=-1, m=-2, s=4, A=2),                 # C / V = A s / V
    "Ohm": dict(kg=1, m=2, s=-3, A=-2),               # V / A
    "Ohm.m": dict(kg=1, m=3, s=-3, A=-2),
    "Ohm.m2": dict(kg=1, m=4, s=-3, A=-2),
    "m2/A": dict(m=2, A=-1),                          # (Ohm m) / (V/m)
}


def test_project_units_in_modelica_syntax():
    spelled = {"ohm m": "Ohm.m", "N s/m": "N.s/m", "m^3": "m3", "ohm m^2": "Ohm.m2", "m^2/A": "m2/A", "ohm": "Ohm",
               "V/m": "V/m", "": "1", "N/m": "N/m", "kg": "kg"}
    for text, unit in spelled.items():
        assert U.modelica(text) == unit, text
        assert U.modelica(unit) == unit           # a Modelica unit comes back as it is
    from fmu import dfa_actuator, drive_electronics, mass_spring_load
    for module in (dfa_actuator, drive_electronics, mass_spring_load):
        for name, text in module.UNITS.items():
            unit = U.modelica(text)
            assert re.fullmatch(r"[A-Za-z0-9./()]+", unit) and "^" not in unit, (name, unit)
            assert unit in SI, (name, unit)
    for key, spec in P.SPEC.items():
        if spec.kind is float:
            assert U.modelica(spec.unit) in SI, key
    with pytest.raises(ValueError, match="unknown symbol"):
        U.modelica("furlong")


@pytest.mark.parametrize("unit", sorted(SI))
def test_si_exponents(unit):
    factor, dims = U.base_unit(unit)
    assert factor == 1.0 and dims == SI[unit]


def test_display_units():
    assert U.display_factor("m", "mm") == 1000.0
    assert U.display_factor("V", "kV") == 1e-3
    assert U.display_factor("F", "nF") == 1e9
    assert U.display_factor("m", "um") == 1e6
    assert U.display_factor("V/m", "kV/mm") == 1e-6
    assert math.isclose(U.display_factor("rad", "deg"), 180.0 / math.pi, rel_tol=1e-14)
    with pytest.raises(ValueError, match="not a unit of"):
        U.display_factor("m", "kV")
    assert U.DISPLAY["stroke"] == "mm" and U.DISPLAY["voltage"] == "kV"
    # every display unit named is one of its variable's unit
    from fmu import dfa_actuator, drive_electronics, mass_spring_load
    units = {**dfa_actuator.UNITS, **drive_electronics.UNITS, **mass_spring_load.UNITS}
    for name, display in U.DISPLAY.items():
        U.display_factor(U.modelica(units[name]), display)
    u = U.unit_definition("m", ["mm"])
    assert u.find("BaseUnit").attrib == {"m": "1"}
    assert u.find("DisplayUnit").attrib == {"name": "mm", "factor": "1000"}


def test_ranges_come_from_the_checks():
    """min/max written for the actuator are parameters.SPEC's and limits' bounds, and a
    value the slave accepts lies within them."""
    from dfa_model import limits
    from fmu import dfa_actuator as D
    for key, spec in P.SPEC.items():
        if spec.kind is not str:
            assert D.PARAM_RANGES[key] == (spec.lo, spec.hi), key
    assert D.PARAM_RANGES["x0"] == (0.0, None) and D.PARAM_RANGES["v_nominal"] == (0.0, None)
    assert D.RANGES["voltage"] == (-limits.MAX_VOLTAGE, limits.MAX_VOLTAGE)
    D._check_param("x0", 0.0)
    for bad in (-1e-9, float("nan"), True):
        with pytest.raises(P.ParameterError, match="x0"):
            D._check_param("x0", bad)
    with pytest.raises(P.ParameterError, match="v_nominal"):
        D._check_param("v_nominal", 0.0)


def test_ssd_carries_omsimulators_annotation():
    """OMSimulator's importer (oms_importFile) makes the system from its vendor
    annotation and matches the prefixed names literally; the SSD still validates
    against the SSP 1.0 schema (fmpy's copy)."""
    from lxml import etree

    from fmu.ssp import OMS, SSC, SSD, STEP, system_description
    text = system_description().decode()
    root = etree.fromstring(text.encode())
    ns = {"ssd": SSD, "ssc": SSC, "oms": OMS}
    master = root.findall("ssd:System/ssd:Annotations/ssc:Annotation[@type='org.openmodelica']/oms:Annotations/"
                          "oms:SimulationInformation/oms:FixedStepMaster", ns)
    assert len(master) == 1
    assert master[0].get("description") == "oms-ma" and float(master[0].get("stepSize")) == STEP
    assert root.find("ssd:System", ns)[-1].tag == f"{{{SSD}}}Annotations"     # last, as the schema orders it
    info = root.find("ssd:DefaultExperiment/ssd:Annotations/ssc:Annotation/oms:Annotations/oms:SimulationInformation",
                     ns)
    assert info is not None and info.get("resultFile") and int(info.get("bufferSize")) > 0
    for tag in ("<ssd:Annotations>", '<ssc:Annotation type="org.openmodelica">', "<oms:Annotations>",
                "<oms:SimulationInformation>", "<oms:FixedStepMaster "):
        assert tag in text, tag
    fmpy_ssd = pytest.importorskip("fmpy.ssp.ssd")
    fmpy_ssd.validate_tree(root, "SystemStructureDescription.xsd")
    units = {u.get("name"): u.find("ssc:BaseUnit", ns).attrib for u in root.findall("ssd:Units/ssc:Unit", ns)}
    assert units and all({k: int(v) for k, v in units[u].items()} == SI[u] for u in units)
