"""Build the DFA co-simulation FMU: `dfa fmu build [--preset NAME | --params FILE] [--out FILE.fmu]
[--fmi 2|3]`.

FMI 2.0 (the default): pythonfmu packs the slave (fmu/dfa_actuator.py) and its parameter
file. FMI 3.0 (`--fmi 3`): pythonfmu3 packs fmu/dfa_actuator3.py. Both slaves are thin
adapters of one implementation, fmu/actuator_core.py. This module then fixes what
pythonfmu(3) leaves out, for either version:

- modelDescription.xml (_fix_description, the one place that writes these): the unit
  of every Real in Modelica syntax ("Ohm.m", "N.s/m"; "1" if dimensionless), each
  defined in <UnitDefinitions> with its SI base-unit exponents and display units
  (fmu/units.py: "mm" for the stroke, "kV" for the voltage); min and max of every
  parameter and input with a range (the slave modules' RANGES, from the checks their
  setters make: dfa_model.limits and dfa_model.io.parameters.SPEC for the actuator);
  nominal values of the actuator's voltage and outputs for the parameters it was built
  from; and the ModelStructure's InitialUnknowns (FMI 2.0 requires the outputs with
  initial = calculated there; pythonfmu writes only <Outputs>, which fmpy's validation
  rejects). pythonfmu (0.7) writes none of the attributes itself;
- the binary: ours (fmu/c/fmi2_loader.c and fmu/c/fmi2_python.c, compiled here with
  the system C compiler) replaces pythonfmu's library, which maps every Python exception
  to fmi2Fatal and destroys the instance (ours keeps the FMI state machine and checks
  every call; see the file's header), and which leaves libpython undeclared so that a C
  host dlopening it with RTLD_NOW fails with `undefined symbol: _Py_NoneStruct`. Ours
  loads libpython itself (the loader) and says what is missing when it cannot.

FMI 3.0 differs in names, not in guarantees: Float64/Int32 variables carrying their own
attributes and value references, the independent variable `time`, a ModelStructure of
<Output>/<InitialUnknown> elements whose dependencies are value references, the
CoSimulation flags canGetAndSetFMUState/canSerializeFMUState (and
canHandleVariableCommunicationStepSize, which pythonfmu3 0.3.4 writes wrong), the binary
in binaries/x86_64-linux; the binary is fmu/c/fmi3_loader.c and fmu/c/fmi3_python.c
(which compiles fmi2_python.c for FMI 3.0), replacing pythonfmu3's library, which
crashes its host after any Python exception (see fmi3_python.c's header).
"""
from __future__ import annotations

import importlib
import math
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import zipfile
from pathlib import Path
from xml.etree import ElementTree as ET

from dfa_model.io import parameters as P
from dfa_model.io.fileio import file_mode, write_atomic

HERE = Path(__file__).resolve().parent
SLAVE = HERE / "dfa_actuator.py"
SLAVE3 = HERE / "dfa_actuator3.py"    # the FMI 3.0 slave
CORE = HERE / "actuator_core.py"      # the slaves' one implementation (both FMI versions)
MODEL_IDENTIFIER = "DFAActuator"
FMI_VERSIONS = (2, 3)


class BuildError(RuntimeError):
    pass


def build_fmu(params: P.Parameters | None = None, out: str | os.PathLike = "DFAActuator.fmu", fmi: int = 2) -> Path:
    """Build the actuator FMU for `params` (default: the Table 1 preset), FMI 2.0 (default)
    or 3.0 (`fmi=3`) co-simulation; returns its path."""
    if fmi not in FMI_VERSIONS:
        raise BuildError(f"--fmi: got {fmi!r}, expected 2 or 3")
    if fmi == 3:
        return build_actuator_variant(SLAVE3, "DFAActuator3", out, params, fmi=3)
    return build_actuator_variant(SLAVE, MODEL_IDENTIFIER, out, params)


def build_actuator_variant(script: str | os.PathLike, cls: str, out: str | os.PathLike,
                           params: P.Parameters | None = None, fmi: int = 2) -> Path:
    """Build an FMU whose slave class `cls` lives in `script` and may build on the
    actuator: the FMU's resources also hold actuator_core.py and dfa_actuator.py
    (importable as `actuator_core`, `dfa_actuator`), the parameter file and the search
    path. build_fmu is the case script = dfa_actuator.py (FMI 3.0: dfa_actuator3.py);
    the tests' fault-injection slave is another."""
    params = P.preset("vshape-table1") if params is None else params
    script = Path(script)
    with tempfile.TemporaryDirectory(prefix="dfa_fmu_") as tmp:
        src = Path(tmp) / "files"
        src.mkdir()
        params.save(src / "dfa_params.toml")
        bundle_model(src / BUNDLED)
        (src / "RUNTIME.txt").write_text("# what the FMU needs in the Python that runs it (pip install ...)\n"
                                         + "\n".join(runtime_requirements()) + "\n")
        variant = script.resolve() not in (SLAVE, SLAVE3)
        shutil.copy2(CORE, src / CORE.name)
        if variant:
            shutil.copy2(SLAVE, src / SLAVE.name)
        from .actuator_core import EXTRA, PARAM_RANGES, RANGES, UNITS
        flags = {"canGetAndSetFMUstate": True} if fmi == 2 else {}     # FMI 3.0: set in _fix_description
        return _package(script, cls, out, list(src.iterdir()), units={**UNITS, "time": "s"}, serialize=True,
                        beside=[CORE, SLAVE] if variant else [CORE], ranges={**RANGES, **PARAM_RANGES},
                        nominals=actuator_nominals(params, EXTRA["v_nominal"][1]), fmi=fmi, **flags)


def actuator_nominals(params: P.Parameters, v_nominal: float) -> dict:
    """Nominal values (FMI's `nominal`: the magnitude a tool scales tolerances and plots
    by) of the actuator's voltage and outputs, for `params` at the voltage v_nominal:
    the stroke range x_e, the electrode length, the initial angle, the capacitance of
    the unzipped actuator, the static zipping force and the stored energy at v_nominal.
    Only finite positive values (FMI 2.0 requires nominal > 0)."""
    from dfa_model.numerics.solver import zip_force_per_volt2
    from dfa_model.numerics.stepper import OUTPUTS, Stepper
    st = Stepper(params, v_nominal=v_nominal)
    c0 = float(st.out[list(OUTPUTS).index("capacitance")])
    values = {"voltage": v_nominal, "stroke": st.model.kin.x_e, "zipped_length": params.l_e,
              "zipping_angle": params.theta0, "capacitance": c0,
              "electrostatic_force": zip_force_per_volt2(st.model) * v_nominal ** 2,
              "stored_energy": 0.5 * c0 * v_nominal ** 2}
    return {k: float(v) for k, v in values.items() if math.isfinite(v) and v > 0}


BUNDLED = "_dfa_model"     # the package's name inside the FMU (dfa_actuator.py imports it)
# runtime dependencies the FMU names when one is missing (pyproject.toml's, minus the
# ones the FMU never imports)
FMU_RUNTIME = ("numpy", "scipy", "numba")


def runtime_requirements() -> list[str]:
    """The project's requirement specifiers for the FMU's runtime dependencies."""
    import re
    from importlib import metadata
    try:
        reqs = metadata.requires("dfa-toolkit") or []
    except metadata.PackageNotFoundError:
        reqs = []
    found = {re.split(r"[ <>=!~;\[]", r, maxsplit=1)[0].lower(): r.split(";")[0].strip() for r in reqs}
    return [found.get(name, name) for name in FMU_RUNTIME]


def bundle_model(dest: Path) -> None:
    """Copy the model package (its sources, presets and the kernels compiled ahead of
    time) to dest, under the name BUNDLED: the FMU runs its own copy wherever it goes.
    If this installation has no current compiled kernels, compile them for the FMU now
    (dfa_model/aot.py; about 30 s, then kept in ~/.cache/dfa-toolkit per source version):
    without them the FMU would compile with numba at every instantiation in a fresh
    extraction folder."""
    from dfa_model import _jit
    pkg = Path(_jit.__file__).parent
    dest.mkdir()
    for f in pkg.rglob("*.py"):           # the package and its role subpackages (physics, numerics, io)
        if "__pycache__" not in f.parts:
            (dest / f.relative_to(pkg)).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(f, dest / f.relative_to(pkg))
    shutil.copytree(pkg / "presets", dest / "presets")
    name = _jit.AOT_MODULE + sysconfig.get_config_var("EXT_SUFFIX")
    if _jit.AOT is not None and Path(_jit.AOT.__file__).exists():
        shutil.copy2(_jit.AOT.__file__, dest / name)
        return
    # compiled once per source version and Python, kept in the user's cache
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "dfa-toolkit" / _jit.source_digest()[:16]
    if not (cache / name).exists():
        cache.mkdir(parents=True, exist_ok=True)
        env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(pkg.parent), os.environ.get("PYTHONPATH", "")]))
        with tempfile.TemporaryDirectory(dir=cache) as part:
            r = subprocess.run([sys.executable, "-m", "dfa_model.aot", "--out", part], capture_output=True, text=True,
                               env=env)
            if r.returncode != 0 or not (Path(part) / name).exists():
                raise BuildError("compiling the kernels for the FMU failed (python -m dfa_model.aot):\n"
                                 + (r.stdout + r.stderr).strip()[-2000:])
            os.replace(Path(part) / name, cache / name)
    shutil.copy2(cache / name, dest / name)


# the co-simulation example's companions: slave module, slave class
COMPANIONS = {"drive": ("drive_electronics", "DriveElectronics"), "load": ("mass_spring_load", "MassSpringLoad")}


def build_companion_fmu(kind: str, out: str | os.PathLike, start: dict | None = None,
                        files: dict | None = None) -> Path:
    """Build the drive-electronics ("drive") or mass-spring load ("load") FMU.

    `start`: parameter name -> start value. Written to resources/start_values.json,
    which the slave applies at instantiation through its own checks: pythonfmu reads the
    start values off an instance of the slave (made with the resources at hand), so the
    model description states them and every instance starts from them, whatever the
    master (fmpy's SSP master sets none). `files`: more resources, name -> bytes (the
    drive's resources/drive_protocol.json). Neither given: the FMU as it always was."""
    if kind not in COMPANIONS:
        raise BuildError(f"kind: got {kind!r}, expected one of {', '.join(COMPANIONS)}")
    import importlib
    import json
    name, cls = COMPANIONS[kind]
    module = importlib.import_module(f".{name}", __package__)
    with tempfile.TemporaryDirectory(prefix="dfa_fmu_") as tmp:
        res = {**(files or {})}
        if start:
            res[module.START_FILE] = json.dumps(start, indent=1).encode()
        for fname, data in res.items():
            (Path(tmp) / fname).write_bytes(data)
        try:
            return _package(HERE / f"{name}.py", cls, out, [Path(tmp) / f for f in res], units=module.UNITS,
                            ranges=module.RANGES)
        except ValueError as exc:      # the slave refused a start value or a resource
            raise BuildError(f"{kind} FMU: {exc}") from None


def _package(script: Path, cls: str, out, project_files, units: dict, serialize=False, beside=(), ranges=None,
             nominals=None, fmi=2, **flags) -> Path:
    """pythonfmu (FMI 3.0: pythonfmu3) packs the slave; _rewrite fixes the description
    (units: variable name -> unit, the slave module's UNITS; ranges: variable name ->
    (min, max), None for no bound, its RANGES; nominals: variable name -> nominal value)
    and adds our binary. `beside`: modules the script imports, copied next to it
    (pythonfmu imports the script to read its interface)."""
    package = "pythonfmu" if fmi == 2 else "pythonfmu3"
    try:
        FmuBuilder = importlib.import_module(package).FmuBuilder
    except ImportError:
        raise BuildError(f"{package} is not installed: pip install 'dfa-toolkit[fmu]'") from None
    out = output_path(out, ".fmu")
    with tempfile.TemporaryDirectory(prefix="dfa_fmu_") as tmp:
        tmp = Path(tmp)
        src = tmp / "src"
        src.mkdir()
        shutil.copy2(script, src / script.name)
        for extra in beside:
            shutil.copy2(extra, src / Path(extra).name)
        raw = FmuBuilder.build_FMU(src / script.name, dest=tmp / f"{cls}.fmu", project_files=project_files,
                                   needsExecutionTool=True, **flags)
        _rewrite(Path(raw), out, tmp, cls, units, serialize, ranges or {}, nominals or {}, fmi)
    return out


def _rewrite(raw: Path, out: Path, tmp: Path, cls: str, units, serialize, ranges, nominals, fmi=2) -> None:
    # pythonfmu3 also packs the sources of its library (sources/): not our binary's
    with zipfile.ZipFile(raw) as zin:
        entries = {name: zin.read(name) for name in zin.namelist()
                   if not name.startswith(("binaries/", "sources/"))}
    entries["modelDescription.xml"] = _fix_description(entries["modelDescription.xml"], units, serialize, ranges,
                                                       nominals)
    mid = ET.fromstring(entries["modelDescription.xml"]).find("CoSimulation").get("modelIdentifier")
    entries["resources/slaveclass.txt"] = (cls + "\n").encode()
    # a C host's Python when DFA_FMU_PYTHON names none: this one (fmi2_loader.c, fmi2_python.c)
    entries["resources/python.txt"] = (sys.executable + "\n").encode()
    loader, implementation = compile_binary(tmp, mid, fmi)
    entries[f"binaries/{_platform(fmi)}/{mid}.so"] = loader
    entries[f"binaries/{_platform(fmi)}/{mid}-python.so"] = implementation
    write_zip(out, {name: data for name, data in entries.items() if "__pycache__" not in name})


def output_path(out, suffix: str, hint: str = "") -> Path:
    """`out` as a Path, which must end in `suffix` (BuildError otherwise: `hint` says
    when), with its folder created."""
    out = Path(out)
    if out.suffix != suffix:
        raise BuildError(f"--out: expected a file name ending in {suffix}{hint}, got {str(out)!r}")
    out.parent.mkdir(parents=True, exist_ok=True)
    return out


def write_zip(out: Path, entries: dict) -> None:
    """The archive `out` of entries (name in the archive -> bytes), complete or not at all.
    The archive and its entries have the mode of a new file under the user's umask (0o644
    under 0o022; binaries/*.so also executable where readable), so that a tool unpacking
    it with the modes (unzip) gives files others can read too; zipfile's writestr alone
    marks every entry 0o600."""
    import time

    def write(tmp):
        mode = file_mode(tmp) & 0o666                 # the new file's: 0o666 less the umask
        stamp = time.localtime()[:6]
        with zipfile.ZipFile(tmp, "w", zipfile.ZIP_DEFLATED) as z:
            for name, data in entries.items():
                info = zipfile.ZipInfo(name, date_time=stamp)
                info.compress_type = zipfile.ZIP_DEFLATED
                if name.endswith("/"):                      # a folder: searchable where readable
                    info.external_attr = (0o040000 | mode | (mode & 0o444) >> 2) << 16 | 0x10
                elif name.startswith("binaries/") and name.endswith(".so"):
                    info.external_attr = (0o100000 | mode | (mode & 0o444) >> 2) << 16
                else:
                    info.external_attr = (0o100000 | mode) << 16
                z.writestr(info, data)
    write_atomic(out, write)


def _platform(fmi: int = 2) -> str:
    """The binaries' folder: FMI 2.0's platform name (linux64), FMI 3.0's platform tuple
    (<architecture>-linux)."""
    if not sys.platform.startswith("linux") or sys.maxsize < 2 ** 32:
        raise BuildError(f"dfa fmu build supports 64-bit Linux only (this is {sys.platform})")
    if fmi == 2:
        return "linux64"
    import platform
    arch = {"x86_64": "x86_64", "amd64": "x86_64", "aarch64": "aarch64", "arm64": "aarch64"}.get(
        platform.machine().lower())
    if arch is None:
        raise BuildError(f"dfa fmu build --fmi 3: no FMI 3.0 platform tuple for {platform.machine()}")
    return f"{arch}-linux"


def compile_binary(tmp: Path, name: str, fmi: int = 2) -> tuple[bytes, bytes]:
    """Compile the FMU's binary against this Python: the loader (fmu/c/fmi2_loader.c,
    the <name>.so a host loads; libc only) and the implementation (fmu/c/fmi2_python.c,
    <name>-python.so); for FMI 3.0 fmi3_loader.c and fmi3_python.c (which includes
    fmi2_python.c), exporting the fmi3 functions only. The implementation leaves
    CPython's symbols to the process: a Python host has them, and for a C host the loader
    loads libpython first, so that a missing Python is an error status with a log line
    instead of a dlopen failure."""
    import fmpy
    loader_c, impl_c = (HERE / "c" / f"fmi{fmi}_loader.c"), (HERE / "c" / f"fmi{fmi}_python.c")
    cc = os.environ.get("CC") or shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
    if not cc:
        raise BuildError(f"no C compiler found (cc, gcc or clang; or set CC): the FMU's binary is compiled "
                         f"from fmu/c/{loader_c.name} and fmu/c/{impl_c.name}")
    lib = libpython()
    include = sysconfig.get_paths()["include"]
    if not (Path(include) / "Python.h").exists():
        raise BuildError(f"Python.h not found in {include}: install this Python's development headers")
    headers = str(Path(fmpy.__file__).parent / "c-code")      # the FMI 2.0 and 3.0 headers
    if not (Path(headers) / f"fmi{fmi}Functions.h").exists():
        raise BuildError(f"fmpy's FMI {fmi} headers not found in {headers}: pip install 'fmpy>=0.3.20'")
    loader, implementation = tmp / f"{name}.so", tmp / f"{name}-python.so"
    exports = []
    if fmi == 3:      # the FMI 3.0 binary exports FMI 3.0's functions only (not fmi2_python.c's)
        script = tmp / "fmi3.map"
        script.write_text("{ global: fmi3*; local: *; };\n")
        exports = [f"-Wl,--version-script={script}"]
    # -ffp-contract=off: the fast steps' polynomial must round as NumPy's does (no FMA);
    # -Bsymbolic: the implementation's calls stay inside it, whatever the host exports
    cmds = [[cc, "-shared", "-fPIC", "-O2", "-ffp-contract=off", "-Wl,-Bsymbolic", *exports, "-o", str(implementation),
             str(impl_c), "-I", str(HERE / "c"), "-I", headers, "-I", include, "-ldl", "-lm", "-lpthread"],
            [cc, "-shared", "-fPIC", "-O2", *exports, "-o", str(loader), str(loader_c), "-I", str(HERE / "c"),
             "-I", headers, f"-DDFA_PY_MAJOR={sys.version_info.major}", f"-DDFA_PY_MINOR={sys.version_info.minor}",
             f'-DDFA_LIBPYTHON="{lib.name}"', f'-DDFA_LIBDIR="{lib.parent}"', "-ldl", "-lpthread"]]
    for cmd in cmds:
        r = subprocess.run(cmd, capture_output=True, text=True)
        if r.returncode != 0:
            raise BuildError(f"compiling the FMU binary failed:\n{' '.join(cmd)}\n{r.stderr.strip()}")
    return loader.read_bytes(), implementation.read_bytes()


# the attributes of a <Real> in the FMI 2.0 schema's order (written in that order)
_REAL_ATTRS = ("declaredType", "quantity", "unit", "displayUnit", "relativeQuantity", "min", "max", "nominal",
               "unbounded", "start", "derivative", "reinit")
# FMI 3.0: a variable's own attributes (Float64's, the others' a subset), in the schema's order
_FLOAT64_ATTRS = ("name", "valueReference", "description", "causality", "variability", "initial",
                  "canHandleMultipleSetPerTimeInstant", "intermediateUpdate", "previous", "clocks", "declaredType",
                  "quantity", "unit", "displayUnit", "relativeQuantity", "unbounded", "min", "max", "nominal", "start",
                  "derivative", "reinit")
# FMI 3.0 co-simulation capabilities (fmu/c/fmi3_python.c): what pythonfmu3 leaves out or gets wrong
# (0.3.4 writes canHandleVariableCommunicationStepSize as the last option's value)
_FMI3_COSIMULATION = {"needsExecutionTool": "true", "canBeInstantiatedOnlyOncePerProcess": "false",
                      "canGetAndSetFMUState": "true", "providesDirectionalDerivative": "false",
                      "providesAdjointDerivatives": "false", "providesPerElementDependencies": "false",
                      "canHandleVariableCommunicationStepSize": "true", "maxOutputDerivativeOrder": "0",
                      "providesIntermediateUpdate": "false", "mightReturnEarlyFromDoStep": "false",
                      "canReturnEarlyAfterIntermediateUpdate": "false", "hasEventMode": "false",
                      "providesEvaluateDiscreteStates": "false"}


def _fix_description(xml: bytes, units_of: dict, serialize: bool, ranges: dict | None = None,
                     nominals: dict | None = None) -> bytes:
    """The model description with units, display units, ranges, nominal values and the
    ModelStructure (see the module's docstring), for FMI 2.0 or 3.0 (its fmiVersion).
    units_of: variable name -> unit as the project writes it (fmu.units.modelica
    translates; none: dimensionless, "1")."""
    from . import units as U
    root = ET.fromstring(xml)
    fmi3 = root.get("fmiVersion", "").startswith("3.")
    real, integer = ("Float64", "Int32") if fmi3 else ("Real", "Integer")
    units: dict[str, list] = {}          # Modelica unit -> its display units, in order of use
    outputs: list[str] = []              # FMI 2.0: the variables' indices; FMI 3.0: their value references
    params: list[str] = []
    for i, sv in enumerate(root.find("ModelVariables"), start=1):
        name = sv.get("name")
        typed = sv if fmi3 else sv[0]    # FMI 3.0: the variable element carries its type's attributes
        attrs = dict(typed.attrib)
        if typed.tag == real:
            unit = U.modelica(units_of.get(name, ""))
            attrs["unit"] = unit
            displays = units.setdefault(unit, [])
            if name in U.DISPLAY:
                U.display_factor(unit, U.DISPLAY[name])          # the same quantity, or ValueError
                attrs["displayUnit"] = U.DISPLAY[name]
                if U.DISPLAY[name] not in displays:
                    displays.append(U.DISPLAY[name])
            if name in (nominals or {}):
                attrs["nominal"] = f"{nominals[name]:.16g}"
        if typed.tag in (real, integer) and name in (ranges or {}):
            lo, hi = ranges[name]
            fmt = (lambda v: str(int(v))) if typed.tag == integer else (lambda v: f"{v:.16g}")
            if lo is not None:
                attrs["min"] = fmt(lo)
            if hi is not None:
                attrs["max"] = fmt(hi)
        typed.attrib.clear()
        typed.attrib.update({k: attrs[k] for k in (*(_FLOAT64_ATTRS if fmi3 else _REAL_ATTRS), *attrs) if k in attrs})
        key = sv.get("valueReference") if fmi3 else str(i)
        if sv.get("causality") == "output":
            outputs.append(key)
        elif sv.get("causality") == "parameter":
            params.append(key)
    # UnitDefinitions must precede ModelVariables (the schemas' order: after the interface
    # elements, before TypeDefinitions, LogCategories, DefaultExperiment, annotations)
    for old in root.findall("UnitDefinitions"):
        root.remove(old)
    ud = ET.Element("UnitDefinitions")
    for unit, displays in units.items():
        ud.append(U.unit_definition(unit, displays))
    children = list(root)
    pos = next(k for k, c in enumerate(children) if c.tag in ("TypeDefinitions", "LogCategories", "DefaultExperiment",
                                                             "VendorAnnotations", "Annotations", "ModelVariables"))
    root.insert(pos, ud)
    cs = root.find("CoSimulation")
    if fmi3:
        for key, value in _FMI3_COSIMULATION.items():
            cs.set(key, value)
        cs.set("canSerializeFMUState", "true" if serialize else "false")
    else:
        # fmi2_python.c serializes the state when the slave can (the actuator: dfa_model.io.statecodec)
        cs.set("canSerializeFMUstate", "true" if serialize else "false")
    ms = root.find("ModelStructure")
    for child in list(ms):
        ms.remove(child)
    # in co-simulation the outputs depend on the state only, not directly on the inputs;
    # after initialization on the parameters only (every slave computes its initial
    # outputs without its inputs): without `dependencies` a master must assume all
    # inputs too, and sees an algebraic loop through the system's feedback connections
    if fmi3:
        for vr in outputs:
            ET.SubElement(ms, "Output", valueReference=vr, dependencies="")
        for vr in outputs:
            ET.SubElement(ms, "InitialUnknown", valueReference=vr, dependencies=" ".join(params))
    else:
        outs = ET.SubElement(ms, "Outputs")
        init = ET.SubElement(ms, "InitialUnknowns")
        for i in outputs:
            ET.SubElement(outs, "Unknown", index=i, dependencies="")
            ET.SubElement(init, "Unknown", index=i, dependencies=" ".join(params))
    ET.indent(root)
    return ET.tostring(root, encoding="UTF-8", xml_declaration=True)


def libpython() -> Path:
    """This interpreter's shared libpython (the FMU runs on the Python that built it)."""
    libdir = sysconfig.get_config_var("LIBDIR") or ""
    name = sysconfig.get_config_var("INSTSONAME") or sysconfig.get_config_var("LDLIBRARY") or ""
    path = Path(libdir) / name
    if not sysconfig.get_config_var("Py_ENABLE_SHARED") or not path.exists():
        raise BuildError(f"this Python has no shared libpython ({path}); the FMU's binary embeds the "
                         f"interpreter through it. Use a Python built with --enable-shared")
    return path
