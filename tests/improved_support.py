"""Checks of what `dfa diagnose` writes for the rest of the toolkit (diagnosis/improved.py):
improved.toml and the recordings' protocol files. Used by the diagnosis tests on every
catalog entry, the null dataset and a nominal correction."""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

from dfa_model.io import parameters

from dfa_model import Protocol

FMU_READY = all(__import__("importlib").util.find_spec(m) for m in ("fmpy", "pythonfmu")) and \
    (shutil.which("cc") or shutil.which("gcc")) is not None


def dfa(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "dfa_model.cli", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


def check_improved(D, report: dict, out: Path, fmu: bool = False) -> None:
    """improved.toml is named in report.json, reads back to the improved model's parameters
    exactly, says each moved value's standard error and nominal value, and runs unchanged:
    in dfa simulate on every recording's protocol file, in the surrogate and, with
    fmu=True, as an FMU that fmpy steps."""
    out = Path(out)
    on_disk = json.loads((out / "report.json").read_text())
    assert on_disk["improved_params"] == report["improved_params"] == "improved.toml"
    path = out / "improved.toml"
    p = parameters.load(path)
    assert p.to_dict() == D.final.params.to_dict()            # exact: every key, every number
    text = path.read_text()
    assert str(D.dataset.folder) in text and "held-out stroke RMSE" in text
    moved = [k for k, v in D.final.params.to_dict().items() if isinstance(v, dict)]
    fitted = {k: v for t in moved for k, v in D.final.params.to_dict()[t].items()
              if D.dataset.params.to_dict()[t].get(k) != v}
    assert fitted, "the diagnosis moved no value (rho_l at least is fitted)"
    for k in fitted:
        line = next(ln for ln in text.splitlines() if ln.startswith(f"{k} ") or ln.startswith(f"{k}="))
        assert "[diagnosis:" in line and "nominal" in line, line
    head = [ln for ln in text.splitlines() if ln.startswith("#  ")]
    nd = D.dataset.params
    for k in fitted:
        entry = next(ln for ln in head if ln.startswith(f"#   {k} = "))
        if not parameters.applies(nd, k):        # a law's key the nominal model has no use for
            assert "not in the nominal model" in entry, entry
    if D.final.params.law == "linear":          # Eq. (21)'s floor is fitted: a standard error of its own
        assert "+-" in next(ln for ln in head if ln.startswith("#   rho_min = "))
    for e in D.kept:                                           # the kept entries' errors in the header
        if e.kind == "physics":
            for key, v in report["missing_physics"][[m["name"] for m in report["missing_physics"]].index(e.name)][
                    "parameters"].items():
                if v["stderr"] and math.isfinite(v["stderr"]):
                    assert f"{key} = " in text and "+-" in text
    # every recording's protocol replays with the improved model
    assert set(report["protocols"]) == {r.name for r in D.dataset.recordings}
    first = True
    for rec in D.dataset.recordings:
        proto = Protocol.from_toml(out / report["protocols"][rec.name])
        assert abs(proto.duration - rec.protocol.duration) < 1e-9
        if first:     # one replay per dataset through the CLI (the others read back above)
            r = dfa("simulate", "--params", "improved.toml", "--protocol", report["protocols"][rec.name], "--json",
                    cwd=out)
            assert r.returncode == 0, r.stderr
            first = False
    # the surrogate takes it (every catalog entry reduces since issue 23) and runs
    import numpy as np
    import reduced
    s = reduced.build(p, "charge")
    r = s.simulate(Protocol.reset_then_hold(5000.0, 3.0), 3.0)
    x = r.trace(np.linspace(0.0, r.trace.t1, 200))
    assert np.all(np.isfinite(x)) and r.trace.max() > 0
    if fmu and FMU_READY:
        r = dfa("fmu", "build", "--params", path, "--out", out / "improved.fmu")
        assert r.returncode == 0, r.stderr
        import fmpy
        res = fmpy.simulate_fmu(str(out / "improved.fmu"), stop_time=0.05, step_size=1e-3,
                                start_values={"voltage": 5000.0, "force": 3.0})
        assert res["stroke"][-1] > 0
