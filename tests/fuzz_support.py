"""Shared by the fuzz tests: run `dfa` in-process, check an outcome against the contract
(README, 'Reliability'), and count outcomes for the summary line at the end of the run."""
from __future__ import annotations

import contextlib
import io
import json
import math
import os
import re
from collections import Counter

from dfa_model.io.parameters import SPEC

COUNTS: Counter = Counter()
# no case may work longer (the runs are bounded by --max-steps): a guard against a runaway
# case, counted in CPU seconds of this process and its children, not wall time - on the
# 2-core CI machine a case waits for the other worker's FMU builds and pip installs
# (a 3.5 s `dfa reduce` once took 62.8 s of wall time there)
CASE_SECONDS = 60.0

FLAGS = {"--preset", "--params", "--set", "--voltage", "--force", "--waveform", "--frequency", "--duty", "--reset",
         "--reset-frequency", "--duration", "--dt", "--max-steps", "--out", "--plot", "--json", "--vary", "--workers",
         "--scheduler", "--quiet",
         # the commands that came after the first fuzz suite (reduce, compare, design, hold, diagnose, fmu build)
         "--protocol", "--family", "--model", "--max-ripple", "--max-drift", "--horizon", "--slew-rate",
         "--current-limit", "--stroke", "--system", "--drive", "--fmi"}
NAMES = set(SPEC) | {"layout", "params", "preset", "voltage", "force", "frequency", "duty", "reset", "reset_frequency",
                     "duration", "theta0", "max_steps", "t_eval", "x0", "y0", "V_before", "simulate", "rtol",
                     "command", "fmu_command", "k_load"} | {
                        f"{t}.{k}" for t in ("geometry", "materials", "mechanics", "discretization", "resistivity")
                        for k in (*SPEC, "apex", "junk", "layout")} | {"geometry", "materials", "mechanics",
                                                                       "discretization", "resistivity", "junk"}
PHRASES = ("the following arguments are required", "unrecognized arguments", "one of --preset", "give either",
           "invalid choice")
# an error states what is acceptable, or what to do
HINT = re.compile(r"expected|must|need|limit|appl|unknown|missing|required|valid|does not exist|folder|writable|"
                  r"twice|either|choose from|raise|No such file|[Pp]ermission|known|not a|cannot read|"
                  r"unrecognized|invalid choice|Read-only|not supported|remove|not both|only with|allowed",
                  re.IGNORECASE)
ERROR_NAME = re.compile(r"^(argument )?(?P<name>[-\w.]+)(?: [-\w.]+)*?:")


def cpu_seconds() -> float:
    """CPU time of this process (all its threads) and of its children that have ended."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


def run(argv):
    """(exit code, stdout, stderr, seconds) of `dfa argv`, in this process; seconds are
    CPU seconds (cpu_seconds)."""
    from dfa_model.cli import main
    out, err = io.StringIO(), io.StringIO()
    t0 = cpu_seconds()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        rc = main([str(a) for a in argv])
    return rc, out.getvalue(), err.getvalue(), cpu_seconds() - t0


SUMMARY_KEYS = ("static_stroke", "final_stroke", "unzipping_speed", "wall_time")   # dfa simulate --json


def _about_a_file(msg, files) -> bool:
    """Whether error `msg` starts with one of `files` (the paths or names of the files the
    case gave: a protocol file, a dataset's folder or one of its files, a surrogate), then
    ':' or ', row'/', sample': an error about a file's content is named by the file first."""
    for f in files:
        f = str(f)
        if f and msg.startswith(f) and msg[len(f):].startswith((":", ", row ", ", sample ")):
            return True
    return False


def check(rc, out, err, seconds, x_e=None, kind="cli", files=(), keys=SUMMARY_KEYS, info=False, guard=True):
    """Assert the contract for one outcome and count it. Returns the JSON summary of a
    successful --json run (or None).

    files: the files the case gave (an error about one starts with its path or name);
    keys: the keys of the --json object that must be finite numbers (a NaN would be
    printed as null: json_safe); info: the command prints progress or a summary on stderr
    (reduce, design and hold --json, diagnose), so lines other than warnings and errors
    are allowed there - but never an internal error or a traceback. guard: the runaway guard
    applies (CASE_SECONDS); off for a fixed set-up step that is not a drawn case (its time is
    the command's own, kernels compiled just in time included where the build could not
    compile them ahead)."""
    COUNTS["cases"] += 1
    COUNTS[f"cases:{kind}"] += 1
    if os.environ.get("DFA_FUZZ_LOG"):     # every outcome, one line each (to read what the cases meet)
        with open(os.environ["DFA_FUZZ_LOG"], "a") as log:
            log.write(f"{kind}\t{rc}\t{seconds:.2f}\t{(err.strip().splitlines() or [''])[-1][:300]}\n")
    lines = [ln for ln in err.splitlines() if ln.strip() and not ln.startswith(("sweep:", "\r"))]
    assert not guard or seconds < CASE_SECONDS, f"took {seconds:.1f} s"
    assert "Traceback" not in err and "Traceback" not in out, err[-2000:]
    assert rc in (0, 1, 2), (rc, err[-2000:])
    warn = [ln for ln in lines if ln.startswith("dfa: warning: ")]
    errs = [ln for ln in lines if ln.startswith("dfa: error: ")]
    other = [ln for ln in lines if not ln.startswith(("dfa: warning: ", "dfa: error: ", "dfa: note: "))]
    assert not [ln for ln in lines if "internal error" in ln], err
    assert info or not other, f"unexpected stderr lines: {other}"
    if warn:
        COUNTS["with warnings"] += 1
    if rc == 2:
        COUNTS["clean errors"] += 1
        COUNTS[f"errors:{kind}"] += 1
        assert len(errs) == 1 and lines[-1] == errs[0], err
        msg = errs[0][len("dfa: error: "):]
        assert "nan" not in msg.split(":")[0].lower()
        if not msg.startswith(PHRASES) and not _about_a_file(msg, files):
            m = ERROR_NAME.match(msg)
            assert m, f"the error does not start with what it is about: {msg}"
            name = m.group("name")
            if "unknown" not in msg:    # an unknown key is named as the user wrote it
                assert name in NAMES or name in FLAGS, f"the error names {name!r}, not a flag or key: {msg}"
        assert HINT.search(msg), f"the error does not say what is acceptable: {msg}"
        return None
    assert not errs, err
    if rc == 1:
        COUNTS["partial results (exit 1)"] += 1
        return None
    COUNTS["results"] += 1
    COUNTS[f"results:{kind}"] += 1
    text = out.strip().splitlines()
    if text and text[-1].startswith("{"):
        summary = json.loads(text[-1])
        for key in keys:
            v = summary
            for part in key.split("."):
                v = v[part]
            assert isinstance(v, (int, float)) and math.isfinite(v), (key, summary)
        if x_e is not None:
            for key in ("static_stroke", "final_stroke"):
                assert 0.0 <= summary[key] <= x_e, (key, summary[key], x_e)
        if "unzipping_speed" in keys:
            assert summary["unzipping_speed"] >= 0
        return summary
    return None
