"""Units for the FMUs' model descriptions and the SSP: Modelica unit syntax, SI
base-unit exponents, display units.

The project writes units for people ("ohm m", "N s/m", "m^3": dfa_model.io.parameters.SPEC,
the slave modules' tables); a model description needs them in Modelica syntax (FMI 2.0,
2.2.2: "Ohm.m", "N.s/m", "m3"), each defined once in <UnitDefinitions> with its
exponents of the SI base units (kg, m, s, A, K, mol, cd, rad) and its display units.
Here: `modelica` translates, `base_unit` parses a Modelica unit into factor and
exponents (so no exponent is written by hand), `DISPLAY` names the display unit of a
variable, and `unit_definition` writes a <Unit> element.

Dimensionless Reals get unit "1" (Modelica's dimensionless unit: no exponent).
"""
from __future__ import annotations

import math
import re
from xml.etree import ElementTree as ET

BASE = ("kg", "m", "s", "A", "K", "mol", "cd", "rad")   # FMI 2.0 BaseUnit attributes, in schema order

# unit symbol -> (factor to SI, exponents): the symbols the project uses, and a few more
_SYMBOLS = {
    "kg": (1.0, dict(kg=1)), "g": (1e-3, dict(kg=1)), "m": (1.0, dict(m=1)), "s": (1.0, dict(s=1)),
    "A": (1.0, dict(A=1)), "K": (1.0, dict(K=1)), "mol": (1.0, dict(mol=1)), "cd": (1.0, dict(cd=1)),
    "rad": (1.0, dict(rad=1)), "deg": (math.pi / 180.0, dict(rad=1)),
    "Hz": (1.0, dict(s=-1)), "N": (1.0, dict(kg=1, m=1, s=-2)), "Pa": (1.0, dict(kg=1, m=-1, s=-2)),
    "J": (1.0, dict(kg=1, m=2, s=-2)), "W": (1.0, dict(kg=1, m=2, s=-3)), "C": (1.0, dict(s=1, A=1)),
    "V": (1.0, dict(kg=1, m=2, s=-3, A=-1)), "F": (1.0, dict(kg=-1, m=-2, s=4, A=2)),
    "Ohm": (1.0, dict(kg=1, m=2, s=-3, A=-2)), "S": (1.0, dict(kg=-1, m=-2, s=3, A=2)),
}
_PREFIXES = {"p": 1e-12, "n": 1e-9, "u": 1e-6, "m": 1e-3, "c": 1e-2, "d": 1e-1, "k": 1e3, "M": 1e6, "G": 1e9,
             "T": 1e12}
_OPERAND = re.compile(r"([A-Za-z]+)([+-]?[0-9]+)?$")

# the project's unit text -> Modelica symbol (words people write that Modelica spells otherwise)
_WORDS = {"ohm": "Ohm"}


def modelica(text: str) -> str:
    """The Modelica spelling of a unit as the project writes it: factors separated by
    spaces ("N s/m") joined by ".", powers "m^3" as "m3", "ohm" as "Ohm"; "" (a
    dimensionless quantity) as "1". A Modelica unit comes back as it is. Raises
    ValueError for what it cannot read."""
    text = text.strip()
    if text in ("", "1"):
        return "1"
    parts = text.split("/")
    if len(parts) > 2:
        raise ValueError(f"unit {text!r}: more than one '/'")

    def factors(side):
        out = []
        for word in side.replace(".", " ").split():
            m = re.fullmatch(r"([A-Za-z]+)(?:\^?([+-]?[0-9]+))?", word)
            if not m:
                raise ValueError(f"unit {text!r}: cannot read {word!r}")
            sym, exp = m.group(1), m.group(2)
            out.append(_WORDS.get(sym, sym) + (exp or ""))
        return ".".join(out)

    unit = factors(parts[0]) if parts[0].strip() else "1"
    if len(parts) == 2:
        den = factors(parts[1])
        unit += "/" + (den if "." not in den else f"({den})")
    base_unit(unit)          # refuse a symbol the table cannot resolve
    return unit


def _operand(word: str, unit: str) -> tuple[float, dict]:
    m = _OPERAND.match(word)
    if not m:
        raise ValueError(f"unit {unit!r}: cannot read {word!r}")
    sym, exp = m.group(1), int(m.group(2) or 1)
    if sym in _SYMBOLS:                     # a symbol first: "m" is the metre, "mol" the mole
        factor, dims = _SYMBOLS[sym]
    elif sym[0] in _PREFIXES and sym[1:] in _SYMBOLS and sym[1:] != "kg":
        factor, dims = _SYMBOLS[sym[1:]]
        factor *= _PREFIXES[sym[0]]
    else:
        raise ValueError(f"unit {unit!r}: unknown symbol {sym!r}")
    return factor ** exp, {k: v * exp for k, v in dims.items()}


def base_unit(unit: str) -> tuple[float, dict]:
    """(factor, exponents) of a Modelica unit string: value in SI base units = factor x
    value in `unit`; exponents: base unit -> nonzero exponent. Reads Modelica's grammar
    as far as the units here need: "1", operands "[prefix]symbol[exponent]" joined by
    ".", one "/" with a denominator in parentheses or a single operand."""
    def product(side):
        side = side.strip()
        if side.startswith("(") and side.endswith(")"):
            side = side[1:-1]
        factor, dims = 1.0, {}
        if side == "1":
            return factor, dims
        for word in side.split("."):
            f, d = _operand(word, unit)
            factor *= f
            for k, v in d.items():
                dims[k] = dims.get(k, 0) + v
        return factor, dims

    num, _, den = unit.partition("/")
    factor, dims = product(num)
    if den:
        f, d = product(den)
        factor /= f
        for k, v in d.items():
            dims[k] = dims.get(k, 0) - v
    return _round(factor), {k: v for k, v in dims.items() if v}


# the display unit of a variable (by name), and by unit for variables not named here
DISPLAY = {
    "stroke": "mm", "zipped_length": "mm", "x0": "mm", "mass_position": "mm", "velocity": "mm/s",
    "l": "mm", "a": "mm", "w": "mm", "l_e": "mm", "t_f": "um", "t_lz": "um",
    "voltage": "kV", "v_nominal": "kV", "amplitude": "kV", "slew_rate": "V/us",
    "zipping_angle": "deg", "capacitance": "nF", "load_capacitance": "nF", "current": "uA",
    "supply_current": "mA", "current_limit": "mA", "stored_energy": "mJ", "E_lo": "kV/mm", "E_hi": "kV/mm",
    "tau_p": "ms", "R_s": "MOhm",
}


def display_factor(unit: str, display: str) -> float:
    """FMI 2.0's DisplayUnit factor: display value = factor x value in `unit`. Raises
    ValueError if the two are not the same quantity."""
    fu, du = base_unit(unit)
    fd, dd = base_unit(display)
    if du != dd:
        raise ValueError(f"display unit {display!r} is not a unit of {unit!r}")
    return _round(fu / fd)


def _round(x: float) -> float:
    # prefixes are powers of ten: 1 / 1e-9 is 999999999.9999999 in binary, 1e9 meant
    return float(f"{x:.15g}")


def unit_definition(unit: str, displays=()) -> ET.Element:
    """<Unit name=unit> with its <BaseUnit> (exponents, and factor where not 1) and a
    <DisplayUnit> for each of `displays`."""
    factor, dims = base_unit(unit)
    u = ET.Element("Unit", name=unit)
    attrs = {k: str(dims[k]) for k in BASE if k in dims}
    if factor != 1.0:
        attrs["factor"] = f"{factor:.16g}"
    ET.SubElement(u, "BaseUnit", attrs)
    for d in displays:
        f = display_factor(unit, d)
        ET.SubElement(u, "DisplayUnit", {"name": d} if f == 1.0 else {"name": d, "factor": f"{f:.16g}"})
    return u
