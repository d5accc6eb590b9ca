"""Fuzz suite (issue 8): generated bad and extreme parameter files, flag combinations,
sweeps and API calls. Every case ends in a one-line error naming the flag or key and
what is acceptable (exit 2), or a result with warnings that is finite and within the
stroke's stops: never a traceback, an internal error, a NaN, or a run past the stated
time. Deterministic (derandomized) so that CI runs the same cases; the counts are
printed at the end of the test run."""
from __future__ import annotations

import math
import os
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from dfa_model import DFAModel, parameters, preset  # noqa: E402
from fuzz_support import check, run  # noqa: E402

FUZZ = settings(deadline=None, derandomize=True, database=None, print_blob=True,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much, HealthCheck.data_too_large])
TMP = Path(tempfile.mkdtemp(prefix="dfa_fuzz_"))
STEPS = "20000"       # the stated step limit every fuzzed run gets (bounds its time)


def x_e_of(argv):
    """The stroke range of the case's parameters, if they are valid (else None)."""
    try:
        p = parameters.load(argv[argv.index("--params") + 1]) if "--params" in argv else parameters.preset(
            argv[argv.index("--preset") + 1])
        sets = [argv[i + 1] for i, a in enumerate(argv[:-1]) if a == "--set"]
        return DFAModel(parameters.apply_sets(p, sets)).kin.x_e
    except Exception:
        return None


# ---------------------------------------------------------------- parameter files
WEIRD = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True, width=64),
    st.integers(min_value=-10 ** 6, max_value=10 ** 6),
    st.sampled_from([0, -1, 1e-30, 1e30, 81.0, 2.5, 1e400, -0.0, True, False, "abc", "", "continuum", "paper",
                     "linear", "constant", "v-shaped", "peano-hasel", "6000"]),
    st.lists(st.integers(min_value=0, max_value=9), max_size=2),
)
# plausible values per key (log-uniform around the preset), so some files are valid and run
PLAUSIBLE = st.floats(min_value=-3.0, max_value=3.0)


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return '"' + v.replace('"', "") + '"'
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    return str(v)


def to_toml(d):
    lines = [f"layout = {toml_value(d['layout'])}"] if "layout" in d else []
    for table, content in d.items():
        if table == "layout":
            continue
        lines.append(f"[{table}]")
        for k, v in content.items() if isinstance(content, dict) else []:
            lines.append(f"{k} = {toml_value(v)}")
    return "\n".join(lines) + "\n"


@st.composite
def parameter_files(draw):
    d = preset(draw(st.sampled_from(["vshape-table1", "peano-fig10"]))).to_dict()
    d["mechanics"]["m"] = 0.0
    keys = list(parameters.SPEC)
    for _ in range(draw(st.integers(min_value=1, max_value=3))):
        kind = draw(st.sampled_from(["weird", "weird", "scale", "scale", "delete", "move", "unknown", "layout",
                                     "raw"]))
        key = draw(st.sampled_from(keys))
        table = parameters.SPEC[key].table
        if kind == "weird":
            d.setdefault(table, {})[key] = draw(WEIRD)
        elif kind == "scale":        # a plausible number: often valid, sometimes out of the geometry
            base = d.get(table, {}).get(key, getattr(parameters.Parameters(), key))
            if isinstance(base, (int, float)) and not isinstance(base, bool) and base:
                v = base * 10 ** draw(PLAUSIBLE)
                d.setdefault(table, {})[key] = int(v) if isinstance(base, int) else v
        elif kind == "delete":
            d.get(table, {}).pop(key, None)
        elif kind == "move":
            other = draw(st.sampled_from(list(parameters.TABLES)))
            if key in d.get(table, {}):
                d.setdefault(other, {})[key] = d[table].pop(key)
        elif kind == "unknown":
            d.setdefault(draw(st.sampled_from(list(parameters.TABLES) + ["junk"])), {})["apex"] = 1.0
        elif kind == "layout":
            v = draw(st.sampled_from(["v-shaped", "peano-hasel", "V-shaped", "", None]))
            if v is None:
                d.pop("layout", None)
            else:
                d["layout"] = v
        else:
            return draw(st.sampled_from(["layout = \n", "[geometry\nl = 1\n", "\x00\x01", "layout = 'v-shaped'\n",
                                         "= 3\n", "[geometry]\nl = 1\nl = 2\n", ""]))
    return to_toml(d)


@settings(FUZZ, max_examples=260)
@given(text=parameter_files(), V=st.sampled_from(["6000", "-6000", "1000", "6e5"]),
       F=st.sampled_from(["5", "0", "-5", "1e3"]), wave=st.sampled_from([[], ["--waveform", "bipolar",
                                                                          "--frequency", "100"]]))
def test_parameter_files(text, V, F, wave):
    path = TMP / "p.toml"
    path.write_text(text)
    argv = ["simulate", "--params", path, "--voltage", V, "--force", F, "--duration", "0.05", "--json",
            "--max-steps", STEPS, *wave]
    check(*run(argv), x_e=x_e_of([str(a) for a in argv]), kind="parameter file")


# ---------------------------------------------------------------- flag combinations
NUM = st.sampled_from(["6000", "3000", "-6000", "0", "5", "-1e6", "1e6", "1e9", "-1e9", "nan", "-inf", "inf", "1e-300",
                       "abc", "", "0.02", "0.05", "1e7", "-5", "7", "0.5", "30", "1e4", "81.0", "2"])
SMALL = st.sampled_from(["0.01", "0.02", "0.05", "0.1"])
PATHS = st.sampled_from(["ok.csv", "ok.png", "missing/x.csv", "", ".", "ok.xyz", "/proc/dfa.csv", "sub", "ok"])
SETS = st.builds(lambda k, v: f"{k}={v}", st.sampled_from(list(parameters.SPEC) + ["layout", "foo", "geometry.a", ""]),
                 st.sampled_from(["1e12", "0", "-1", "nan", "inf", "81.0", "2.5", "abc", "", "paper", "linear",
                                  "peano-hasel", "0.0119", "1e-15", "200", "10", "1e-9"]))


# per flag: plausible values (drawn most of the time, so that many cases run the model
# at extremes of its range) and hostile ones
GOOD = {"--voltage": ["6000", "-6000", "3000", "1e5", "0", "100", "1e6"],
        "--force": ["5", "0", "-5", "20", "1e3", "-1e4"],
        "--duration": ["0.01", "0.05", "0.2", "2"],
        "--frequency": ["30", "1000", "0.5", "1e5"],
        "--duty": ["0.5", "1", "0.1"],
        "--reset": ["0.05", "0", "0.2"],
        "--reset-frequency": ["30", "500"],
        "--dt": ["1e-3", "0", "0.3", "1e-5", "100"],
        "--max-steps": [STEPS, "10", "1"]}


@st.composite
def simulate_flags(draw):
    def value(flag):
        return draw(st.sampled_from(GOOD[flag])) if draw(st.integers(0, 7)) else draw(NUM)

    argv = ["simulate"]
    src = draw(st.sampled_from(["preset"] * 6 + ["params", "both", "none", "bad preset"]))
    if src in ("preset", "both"):
        argv += ["--preset", draw(st.sampled_from(["vshape-table1", "peano-fig10"]))]
    if src in ("params", "both"):
        argv += ["--params", draw(st.sampled_from([str(TMP / "good.toml")] * 3 + [str(TMP / "none.toml"), str(TMP)]))]
    if src == "bad preset":
        argv += ["--preset", "table1"]
    if draw(st.integers(0, 3)) == 0:
        argv += ["--set", draw(SETS)]
    argv += ["--voltage", value("--voltage")]
    if draw(st.booleans()):
        argv += ["--force", value("--force")]
    if draw(st.integers(min_value=0, max_value=8)) > 0:
        argv += ["--duration", value("--duration")]
    wave = draw(st.sampled_from(["dc", "dc", "bipolar", "unipolar", "sine", None]))
    if wave:
        argv += ["--waveform", wave]
    if wave in ("bipolar", "unipolar") or draw(st.integers(0, 9)) == 0:
        argv += ["--frequency", value("--frequency")]
        if draw(st.booleans()):
            argv += ["--duty", value("--duty")]
    if draw(st.integers(0, 2)) == 0:
        argv += ["--reset", value("--reset")]
        if draw(st.booleans()):
            argv += ["--reset-frequency", value("--reset-frequency")]
    if draw(st.booleans()):
        argv += ["--dt", value("--dt")]
    argv += ["--max-steps", value("--max-steps") if draw(st.integers(0, 5)) == 0 else STEPS]
    if draw(st.integers(min_value=0, max_value=4)) == 0:
        argv += ["--out", str(TMP / draw(PATHS)) if draw(st.booleans()) else draw(PATHS)]
    if draw(st.integers(min_value=0, max_value=20)) == 0:
        argv += ["--plot", str(TMP / draw(PATHS))]
    if draw(st.integers(min_value=0, max_value=20)) == 0:
        argv += [draw(st.sampled_from(["--bogus", "extra", "--json=1", "--voltage"]))]
    argv += ["--json"]
    return argv


@settings(FUZZ, max_examples=300)
@given(argv=simulate_flags())
def test_simulate_flags(argv):
    (TMP / "good.toml").write_text(preset("vshape-table1").to_toml())
    (TMP / "sub").mkdir(exist_ok=True)
    cwd = os.getcwd()
    os.chdir(TMP)                       # relative --out/--plot paths land in the scratch folder
    try:
        check(*run(argv), x_e=x_e_of(argv), kind="simulate flags")
    finally:
        os.chdir(cwd)


@settings(FUZZ, max_examples=40)
@given(argv=st.lists(st.sampled_from(["params", "--preset", "vshape-table1", "peano-fig10", "--params",
                                      str(TMP / "none.toml"), "fmu", "build", "--out", str(TMP / "missing" / "a.fmu"),
                                      str(TMP / "a.txt"), "bogus", "--help-me", "sweep", "simulate", ""]),
                     min_size=0, max_size=5))
def test_other_commands(argv):
    """Commands and sub-commands with random arguments (no FMU build gets as far as the
    compiler: every --out here is refused first)."""
    if argv[:2] == ["fmu", "build"] and "--out" not in argv:
        argv = argv + ["--out", str(TMP / "missing" / "a.fmu")]
    if argv[:1] == ["sweep"]:
        argv = argv + ["--vary", "nothing=1"]
    rc, out, err, secs = run(argv)
    if rc == 0 and argv[:1] == ["params"]:      # printed a parameter file: it must load
        path = TMP / "printed.toml"
        path.write_text(out)
        parameters.load(path)
    check(rc, "" if argv[:1] == ["params"] else out, err, secs, kind="other commands")


# ---------------------------------------------------------------- sweeps
@settings(FUZZ, max_examples=25)
@given(vary=st.lists(st.sampled_from(["rho_l=2e12,3e12", "rho_l=2e12", "theta0=25,200", "theta0=-1", "a=0.0119,0.06",
                                      "volume=1e-6", "foo=1", "force=5,1e9", "voltage=6000,nan", "N=41,81.0",
                                      "m_rho=1", "law=constant,linear", "duration=0.02,-1", "rho_l", "rho_l=abc"]),
                     min_size=1, max_size=2),
       base=st.sampled_from(["vshape-table1", "peano-fig10"]), out=st.sampled_from(["s.csv", "missing/s.csv", ""]))
def test_sweeps(vary, base, out):
    argv = ["sweep", "--preset", base, "--voltage", "6000", "--force", "5", "--duration", "0.02", "--quiet",
            "--workers", "1", "--set", "N=21"]
    for v in vary:
        argv += ["--vary", v]
    if out:
        argv += ["--out", str(TMP / out)]
    rc, stdout, err, secs = run(argv)
    check(rc, "", err, secs, kind="sweep")
    if rc in (0, 1) and out == "s.csv":
        assert (TMP / out).stat().st_size > 0


# ---------------------------------------------------------------- the Python API
@st.composite
def api_cases(draw):
    name = draw(st.sampled_from(["vshape-table1", "peano-fig10"]))
    p = preset(name)
    changes = {}
    for key in draw(st.lists(st.sampled_from(["rho_l", "rho_f", "eps_r_l", "eps_r_f", "t_f", "t_lz", "b", "m", "k",
                                              "w", "l_e", "N", "rtol"]), max_size=4, unique=True)):
        base = getattr(p, key) or 1.0
        v = base * 10 ** draw(st.floats(min_value=-4, max_value=4))
        changes[key] = int(min(max(v, 3), 400)) if key == "N" else v
    V = draw(st.sampled_from([0.0, 100.0, 6000.0, -6000.0, 3e4, 1e5, 1e6]))
    F = draw(st.sampled_from([0.0, 5.0, -5.0, 50.0, 1e3, -1e4]))
    wave = draw(st.sampled_from(["dc", "bipolar", "unipolar", "reset"]))
    f = draw(st.sampled_from([1.0, 30.0, 1000.0]))
    return name, changes, V, F, wave, f, draw(st.sampled_from([0.02, 0.2, 2.0]))


@settings(FUZZ, max_examples=150)
@given(case=api_cases())
def test_api_physics(case):
    """Valid-looking parameters anywhere in their ranges, any drive: a clean error of the
    package's own kinds, or a finite result inside [0, x_e]."""
    from dfa_model import Bipolar, ParameterError, Protocol, SolverError, Unipolar, WaveformError, simulate
    from fuzz_support import COUNTS
    name, changes, V, F, wave, f, T = case
    COUNTS["cases"] += 1
    COUNTS["cases:api physics"] += 1
    try:
        p = preset(name).replace(**changes)
        proto = {"dc": lambda: Protocol.dc(V, T), "bipolar": lambda: Protocol.single(Bipolar(V, f), T),
                 "unipolar": lambda: Protocol.single(Unipolar(V, f), T),
                 "reset": lambda: Protocol.reset_then_hold(V, T, reset=0.1, reset_frequency=f)}[wave]()
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            r = simulate(p, proto, load=F, max_steps=20000)
    except (ParameterError, WaveformError, SolverError, ValueError) as exc:
        COUNTS["clean errors"] += 1
        COUNTS["errors:api physics"] += 1
        msg = str(exc)
        assert msg and "\n" not in msg and "nan" not in msg.split(":")[0]
        return
    COUNTS["results"] += 1
    COUNTS["results:api physics"] += 1
    if caught:
        COUNTS["with warnings"] += 1
    x_e = r.model.kin.x_e
    for arr in (r.x, r.v, r.I, r.Fe, r.C, r.U):
        assert np.all(np.isfinite(arr))
    assert 0.0 <= r.x.min() and r.x.max() <= x_e
    assert 0.0 <= r.peak_stroke <= x_e and 0.0 <= r.static_stroke <= x_e
    assert math.isfinite(r.unzipping_speed)
