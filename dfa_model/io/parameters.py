"""Typed parameter sets: presets, TOML load/save and validation.

The TOML layout is a public contract (see README): tables `geometry`, `materials`,
`mechanics`, `discretization` and the optional `polarization`, `circuit` and `resistivity`; keys named after the
paper's symbols, SI units. Every key is validated against the range in `SPEC`, and
errors name the key and its allowed range.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
import tomllib
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from types import SimpleNamespace

from .fileio import toml_float

_PKG = __package__.rpartition(".")[0]      # the model package, where presets/ lives

EPS0 = 8.8541878128e-12  # vacuum permittivity, F/m

LAYOUTS = ("v-shaped", "peano-hasel")
SCHEMES = ("continuum", "continuum-p0", "paper")
LAWS = ("constant", "linear", "spline")
PRESETS = {"vshape-table1": "vshape-table1.toml", "peano-fig10": "peano-fig10.toml"}


class ParameterError(ValueError):
    """An invalid parameter: the message names the key and its valid range."""


@dataclass(frozen=True)
class Spec:
    table: str
    unit: str
    description: str
    lo: float | None = None        # exclusive lower bound unless lo_incl
    hi: float | None = None
    lo_incl: bool = False
    kind: type = float
    choices: tuple = ()

    def range_text(self) -> str:
        if self.choices:
            return "one of " + ", ".join(repr(c) for c in self.choices)
        lo = "" if self.lo is None else f"{self.lo:g} {'<=' if self.lo_incl else '<'} "
        hi = "" if self.hi is None else f" <= {self.hi:g}"
        kind = "an integer" if self.kind is int else "a number"
        return f"{kind} with {lo}value{hi}" + (f" ({self.unit})" if self.unit else "")


# Every key of the parameter file, in file order. Bounds are physical plausibility,
# wide enough for any real device; geometric consistency is checked separately.
SPEC: dict[str, Spec] = {
    "l": Spec("geometry", "m", "polymer side length", 0.0, 10.0),
    "a": Spec("geometry", "m", "semi-aperture (v-shaped)", 0.0, 10.0),
    "volume": Spec("geometry", "m^3", "liquid volume per unit pouch (peano-hasel)", 0.0, 1.0),
    "w": Spec("geometry", "m", "electrode width", 0.0, 10.0),
    "l_e": Spec("geometry", "m", "electrode length", 0.0, 10.0),
    "t_f": Spec("materials", "m", "polymer film thickness", 0.0, 1e-2),
    "t_lz": Spec("materials", "m", "residual liquid thickness, zipped", 0.0, 1e-2),
    "eps_r_f": Spec("materials", "", "relative permittivity of the polymer", 1.0, 1e4, True),
    "eps_r_l": Spec("materials", "", "relative permittivity of the liquid", 1.0, 1e4, True),
    "rho_f": Spec("materials", "ohm m", "polymer resistivity", 0.0, 1e25),
    "rho_l": Spec("materials", "ohm m", "liquid resistivity (constant law; q_rho for linear)", 0.0, 1e25),
    "b": Spec("mechanics", "N s/m", "viscous damping (huge values hold the stroke: blocked tests)", 0.0, 1e15),
    "m": Spec("mechanics", "kg", "generalized mass", 0.0, 1e6, True),
    "k": Spec("mechanics", "N/m", "stiffness, dU_m/dx = k x", 0.0, 1e9, True),
    "chi_p": Spec("polarization", "", "strength of the liquid's fast relaxation, delta eps / eps_l (0: none)",
                  0.0, 100.0, True),
    "tau_p": Spec("polarization", "s", "time constant of the liquid's fast relaxation", 0.0, 1e6),
    "R_s": Spec("circuit", "ohm", "series resistance between the source and the device (0: none)", 0.0, 1e13, True),
    "N": Spec("discretization", "", "material points (N - 1 elements)", 3, 100000, True, int),
    "scheme": Spec("discretization", "", "numerical scheme", kind=str, choices=SCHEMES),
    "rho_t_s": Spec("discretization", "ohm m^2", "fictitious series resistance of Eq. (15) (paper scheme)", 0.0, 1e12),
    "rtol": Spec("discretization", "", "relative tolerance of the time integrator", 1e-12, 1e-1, True),
    "law": Spec("resistivity", "", "liquid resistivity law", kind=str, choices=LAWS),
    "m_rho": Spec("resistivity", "m^2/A", "slope of the linear law, Eq. (21)", -1e12, 1e12),
    "q_rho": Spec("resistivity", "ohm m", "intercept of the linear law, Eq. (21)", 0.0, 1e25),
    "rho_min": Spec("resistivity", "ohm m", "floor at which the linear law is clipped", 0.0, 1e25),
    "E_lo": Spec("resistivity", "V/m", "first knot of the spline law (rho_l below it)", 0.0, 1e10),
    "E_hi": Spec("resistivity", "V/m", "last knot of the spline law (constant above it)", 0.0, 1e10),
    "n_knots": Spec("resistivity", "", "spline law: number of knots, evenly spaced in ln |E| from E_lo to E_hi",
                    2, 6, True, int),
    **{f"d_rho{k}": Spec("resistivity", "", f"spline law: ln rho drop from knot {k} to {k + 1} (0 beyond n_knots)",
                         0.0, 50.0, True) for k in range(1, 6)},
}
DROP_KEYS = tuple(f"d_rho{k}" for k in range(1, 6))   # the spline law's drops, as many as its most knots less one
SPLINE_KEYS = ("E_lo", "E_hi", "n_knots", *DROP_KEYS)
TABLES = ("geometry", "materials", "mechanics", "polarization", "circuit", "discretization", "resistivity")
# keys a parameter file must give (others have documented defaults: k = 0, the scheme,
# rtol, rho_t_s, and the constant law); a and volume by layout
REQUIRED = ("l", "w", "l_e", "t_f", "t_lz", "eps_r_f", "eps_r_l", "rho_f", "rho_l", "b", "m", "N")
# the smallest initial angle theta_0: flatter pouches have a stroke range of microns and
# a lever dl_z/dx of thousands, so forces of 1e5 N at working voltages
THETA0_MIN_DEG = 1.0


@dataclass(frozen=True)
class Parameters:
    """One actuator and its numerical settings. SI units throughout."""

    layout: str = "v-shaped"
    l: float = 0.055
    a: float | None = 0.0119
    volume: float | None = None
    w: float = 0.060
    l_e: float = 0.040
    t_f: float = 25e-6
    t_lz: float = 10e-6
    eps_r_f: float = 2.05
    eps_r_l: float = 3.8
    rho_f: float = 1e15
    rho_l: float = 2e12
    b: float = 10.0
    m: float = 0.0
    k: float = 0.0
    chi_p: float = 0.0
    tau_p: float = 1.0
    R_s: float = 0.0
    N: int = 81
    scheme: str = "continuum"
    rho_t_s: float = 100.0
    rtol: float = 1e-4
    law: str = "constant"
    m_rho: float = -3.34e5
    q_rho: float = 20e12
    rho_min: float = 1e11
    E_lo: float = 1e6
    E_hi: float = 1e8
    n_knots: int = 4
    d_rho1: float = 0.0
    d_rho2: float = 0.0
    d_rho3: float = 0.0
    d_rho4: float = 0.0
    d_rho5: float = 0.0

    def __post_init__(self):
        validate(self)
        # one representation per value: integers for integer keys (81.0 in a file, or a
        # NumPy integer, becomes 81), floats for the others
        for key, spec in SPEC.items():
            value = getattr(self, key)
            if value is not None and spec.kind is not str:
                object.__setattr__(self, key, spec.kind(value))

    # derived quantities -------------------------------------------------
    @property
    def eps_f(self) -> float:
        return EPS0 * self.eps_r_f

    @property
    def eps_l(self) -> float:
        return EPS0 * self.eps_r_l

    @property
    def tau_f(self) -> float:
        """Dielectric time constant of the polymer, rho_f eps_f (s)."""
        return self.rho_f * self.eps_f

    @property
    def tau_l(self) -> float:
        """Dielectric time constant of the liquid, rho_l eps_l (s)."""
        return self.rho_l * self.eps_l

    @property
    def theta0(self) -> float:
        """Initial zipping angle (rad): Eq. (18) at l_z = 0 (v-shaped) or the pouch's
        half curvature angle from Eq. (22) (peano-hasel)."""
        if self.layout == "v-shaped":
            return 2.0 * math.asin(self.a / self.l)
        from ..physics.kinematics import PeanoHasel
        return PeanoHasel(self).theta0

    def replace(self, **changes) -> "Parameters":
        """A copy with some keys changed (validated). Changing a key that does not apply
        to the copy's layout, scheme or law (`a` on a peano-hasel pouch, `m_rho` with the
        constant law) is an error: it would have no effect."""
        for key in changes:
            if key != "layout" and key not in SPEC:
                raise ParameterError(f"{key}: unknown key; valid keys are layout, {', '.join(SPEC)}")
        new = dataclasses.replace(self, **changes)
        for key, value in changes.items():
            if value is not None and key in SPEC and not applies(new, key):
                raise ParameterError(not_applicable(new, key))
        return new

    def with_theta0(self, theta0_deg: float, clip_electrode: bool = True) -> "Parameters":
        """V-shaped copy with the semi-aperture set for an initial angle theta_0 (deg).

        With `clip_electrode`, l_e is shortened to fit l_e <= l - a if needed (large
        angles): the front never gets near there, so the dynamics are unaffected."""
        if self.layout != "v-shaped":
            raise ParameterError("theta0: applies only to layout 'v-shaped' (a peano-hasel pouch's angle "
                                 "follows from its volume)")
        if isinstance(theta0_deg, bool) or not isinstance(theta0_deg, numbers.Real) or \
                not THETA0_MIN_DEG <= theta0_deg < 180.0:
            raise ParameterError(f"theta0: got {theta0_deg!r}, expected {THETA0_MIN_DEG:g} <= value < 180 (deg)")
        a = self.l * math.sin(math.radians(theta0_deg) / 2.0)
        l_e = min(self.l_e, 0.999 * (self.l - a)) if clip_electrode else self.l_e
        return self.replace(a=a, l_e=l_e)

    # I/O ----------------------------------------------------------------
    def to_dict(self) -> dict:
        """Nested dict in the parameter-file layout (only keys that apply)."""
        out: dict = {"layout": self.layout}
        for key, spec in SPEC.items():
            if not applies(self, key):
                continue
            out.setdefault(spec.table, {})[key] = getattr(self, key)
        return out

    def to_toml(self) -> str:
        lines = [f'layout = "{self.layout}"']
        for table, keys in self.to_dict().items():
            if table == "layout":
                continue
            lines += ["", f"[{table}]"]
            for key, value in keys.items():
                spec = SPEC[key]
                text = f'"{value}"' if isinstance(value, str) else _fmt(value)
                comment = spec.description + (f", {spec.unit}" if spec.unit else "")
                lines.append(f"{key + ' = ' + text:<28} # {comment}")
        return "\n".join(lines) + "\n"

    def save(self, path) -> None:
        from .fileio import write_text_atomic
        write_text_atomic(path, self.to_toml())


def _fmt(v) -> str:
    # exact: a file written here reads back to the same parameters (improved.toml, surrogates)
    if isinstance(v, int):
        return str(v)
    return toml_float(v)


def applies(p, key: str) -> bool:
    """Whether parameter `key` takes part in the model for p's layout, scheme and law
    (`a` is v-shaped only, `volume` peano-hasel only, `rho_t_s` the paper scheme's,
    `m_rho`, `q_rho`, `rho_min` the linear law's). p: anything with attributes layout,
    scheme and law."""
    if key == "a":
        return p.layout == "v-shaped"
    if key == "volume":
        return p.layout == "peano-hasel"
    if key == "rho_t_s":
        return p.scheme == "paper"
    if key in ("chi_p", "tau_p", "R_s"):
        return p.scheme == "continuum"
    if key in ("m_rho", "q_rho", "rho_min"):
        return p.law == "linear"
    if key in SPLINE_KEYS:
        return p.law == "spline"
    return True


def not_applicable(p, key: str) -> str:
    """The error message for a key given where it takes no part (see applies)."""
    why = {"a": f"layout {p.layout!r} (peano-hasel pouches use volume)",
           "volume": f"layout {p.layout!r} (v-shaped actuators use a)",
           "rho_t_s": f"scheme {p.scheme!r} (only the 'paper' scheme has the series resistance)",
           "chi_p": f"scheme {p.scheme!r} (the fast relaxation is modelled in the 'continuum' scheme)",
           "tau_p": f"scheme {p.scheme!r} (the fast relaxation is modelled in the 'continuum' scheme)",
           "R_s": f"scheme {p.scheme!r} (the series resistance is modelled in the 'continuum' scheme)"}
    if key in SPLINE_KEYS:
        why[key] = f"law {p.law!r} ({', '.join(SPLINE_KEYS)} belong to law = 'spline')"
    reason = why.get(key, f"law {p.law!r} (m_rho, q_rho and rho_min belong to law = 'linear')")
    return f"{SPEC[key].table}.{key}: does not apply to {reason}; remove it, or change that setting"


def validate(p: Parameters) -> None:
    """Raise ParameterError naming the first bad key and its valid range."""
    check_value("layout", p.layout)
    for key, spec in SPEC.items():
        value = getattr(p, key)
        if value is None:
            if applies(p, key):
                raise ParameterError(f"{key}: missing; {spec.table}.{key} is required for layout {p.layout!r}: {spec.range_text()}")
            continue
        check_value(key, value, spec)
    if p.law == "spline" and not p.E_lo < p.E_hi:
        raise ParameterError(f"E_hi: the spline law's last knot {p.E_hi:g} V/m must lie above its first, "
                             f"E_lo = {p.E_lo:g} V/m")
    if p.law == "spline":
        for key in DROP_KEYS[p.n_knots - 1:]:
            if getattr(p, key):
                raise ParameterError(f"{key}: must be 0 with n_knots = {p.n_knots} (a spline of n_knots knots has "
                                     f"n_knots - 1 drops, d_rho1 to d_rho{p.n_knots - 1}); raise n_knots or remove it")
    th_min = math.radians(THETA0_MIN_DEG)
    if p.layout == "v-shaped":
        if p.a >= p.l:
            raise ParameterError(f"a: semi-aperture {p.a:g} m must be smaller than l = {p.l:g} m")
        a_min = p.l * math.sin(th_min / 2)
        if p.a < a_min:
            raise ParameterError(f"a: semi-aperture {p.a:g} m makes the pouch nearly flat (theta_0 = "
                                 f"{math.degrees(2 * math.asin(p.a / p.l)):.3g} deg); need theta_0 >= "
                                 f"{THETA0_MIN_DEG:g} deg, a >= {a_min:.4g} m for l = {p.l:g} m")
        if p.l_e > p.l - p.a:
            raise ParameterError(f"l_e: electrode length {p.l_e:g} m must be <= l - a = {p.l - p.a:g} m")
    else:
        from ..physics.kinematics import peano_lz_max
        lz_max = peano_lz_max(p.l, p.volume / p.w)
        if lz_max <= 0:
            raise ParameterError(f"volume: {p.volume:g} m^3 does not fit a pouch of l = {p.l:g} m, w = {p.w:g} m; "
                                 f"need volume < w l^2 / pi = {p.w * p.l ** 2 / math.pi:.4g} m^3")
        # the liquid cross-section at theta_0 (Eq. 22 with the chord, kinematics.py)
        v_min = p.w * p.l ** 2 / 2 * (th_min - math.sin(th_min) * math.cos(th_min)) / th_min ** 2
        if p.volume < v_min:
            raise ParameterError(f"volume: {p.volume:g} m^3 leaves the pouch nearly flat; need theta_0 >= "
                                 f"{THETA0_MIN_DEG:g} deg, volume >= {v_min:.4g} m^3 for l = {p.l:g} m, w = {p.w:g} m")
        if p.l_e >= lz_max:
            raise ParameterError(f"l_e: electrode length {p.l_e:g} m must be < {lz_max:.4g} m, the zipped length "
                                 f"at which the pouch becomes circular (l - sqrt(pi volume / w))")


def check_value(key: str, value, spec: Spec | None = None) -> None:
    """Raise ParameterError if `value` is outside the range of parameter `key` (or
    is not a layout, for key "layout")."""
    if key == "layout":
        if value not in LAYOUTS:
            raise ParameterError(f"layout: got {value!r}, expected one of {', '.join(map(repr, LAYOUTS))}")
        return
    spec = SPEC[key] if spec is None else spec
    if spec.choices:
        if value not in spec.choices:
            raise ParameterError(f"{key}: got {value!r}, expected {spec.range_text()}")
        return
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(f"{key}: got {value!r}, expected {spec.range_text()}")
    if not math.isfinite(value):
        raise ParameterError(f"{key}: got {value!r}, expected {spec.range_text()}")
    if spec.kind is int and int(value) != value:
        raise ParameterError(f"{key}: got {value!r}, expected {spec.range_text()}")
    bad_lo = spec.lo is not None and (value < spec.lo or (value == spec.lo and not spec.lo_incl))
    bad_hi = spec.hi is not None and value > spec.hi
    if bad_lo or bad_hi:
        raise ParameterError(f"{key}: got {value:g}, expected {spec.range_text()}")


def coerce(key: str, text: str):
    """Parse a `--set KEY=VALUE` value for `key` (a bare key or table.key)."""
    key = key.split(".")[-1]
    if key == "layout":
        return key, text
    if key not in SPEC:
        raise ParameterError(f"{key}: unknown key; valid keys are layout, {', '.join(SPEC)}")
    spec = SPEC[key]
    if spec.kind is str:
        return key, text.strip().strip('"')
    try:
        value = float(text)
    except ValueError:
        raise ParameterError(f"{key}: got {text!r}, expected {spec.range_text()}") from None
    check_value(key, value, spec)
    return key, spec.kind(value)


def from_dict(data: dict, source: str = "parameters") -> Parameters:
    """Build Parameters from the nested parameter-file layout; unknown or missing keys
    are errors that name the key."""
    data = dict(data)
    layout = data.pop("layout", None)
    if layout is None:
        raise ParameterError(f"layout: missing in {source}; expected one of {', '.join(map(repr, LAYOUTS))}")
    check_value("layout", layout)
    flat: dict = {"layout": layout}
    for table, content in data.items():
        if table not in TABLES:
            raise ParameterError(f"{table}: unknown table or key in {source}; valid tables are {', '.join(TABLES)}")
        if not isinstance(content, dict):
            raise ParameterError(f"{table}: expected a table [{table}] in {source}")
        for key, value in content.items():
            if key not in SPEC or SPEC[key].table != table:
                valid = [k for k, s in SPEC.items() if s.table == table]
                raise ParameterError(f"{table}.{key}: unknown key in {source}; valid keys in [{table}] are {', '.join(valid)}")
            flat[key] = value
    for key in (*REQUIRED, "a" if layout == "v-shaped" else "volume"):
        if key not in flat:
            raise ParameterError(f"{SPEC[key].table}.{key}: missing in {source}; expected {SPEC[key].range_text()}")
    # a key that takes no part would be silently ignored: refuse it (applies() needs
    # the file's own scheme and law, so check them first)
    for key in ("scheme", "law"):
        if key in flat:
            check_value(key, flat[key])
    setting = SimpleNamespace(layout=layout, scheme=flat.get("scheme", "continuum"), law=flat.get("law", "constant"))
    for key in flat:
        if key != "layout" and not applies(setting, key):
            raise ParameterError(not_applicable(setting, key) + f" (in {source})")
    if layout == "v-shaped":
        flat.setdefault("volume", None)
    else:
        flat.setdefault("a", None)
    return Parameters(**flat)        # __post_init__ validates every value


def load(path) -> Parameters:
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as exc:
        raise ParameterError(f"params: cannot read {path}: {exc.strerror}") from None
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise ParameterError(f"params: {path} is not valid TOML: {exc}") from None
    return from_dict(data, source=str(path))


def preset(name: str) -> Parameters:
    if name not in PRESETS:
        raise ParameterError(f"preset: unknown preset {name!r}; available: {', '.join(PRESETS)}")
    text = resources.files(_PKG).joinpath("presets", PRESETS[name]).read_text()
    return from_dict(tomllib.loads(text), source=f"preset {name}")


def preset_text(name: str) -> str:
    """The preset file as shipped (with comments)."""
    preset(name)  # validates the name
    return resources.files(_PKG).joinpath("presets", PRESETS[name]).read_text()


def apply_sets(p: Parameters, assignments) -> Parameters:
    """Apply `KEY=VALUE` strings (CLI --set)."""
    changes = {}
    for item in assignments or ():
        if "=" not in item:
            raise ParameterError(f"--set: expected KEY=VALUE, got {item!r}")
        key, text = item.split("=", 1)
        if not key.strip():
            raise ParameterError(f"--set: expected KEY=VALUE with a key, got {item!r}")
        key, value = coerce(key.strip(), text.strip())
        if key in changes:
            raise ParameterError(f"--set: {key} given twice ({changes[key]!r} and {value!r})")
        changes[key] = value
    if "layout" in changes and changes["layout"] != p.layout:
        raise ParameterError(f"layout: cannot be changed with --set (expected {p.layout!r}, the file's own); "
                             f"use a parameter file with the other layout's keys")
    return p.replace(**changes) if changes else p
