"""examples/reduced_report.py: the --quick report runs and marks held-out rows honestly."""
import csv
import importlib.util
import sys
from pathlib import Path

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_quick_report(tmp_path, monkeypatch):
    monkeypatch.syspath_prepend(str(EXAMPLES))
    monkeypatch.setenv("DFA_EXAMPLES_OUT", str(tmp_path))
    spec = importlib.util.spec_from_file_location("reduced_report", EXAMPLES / "reduced_report.py")
    mod = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "reduced_report", mod)
    spec.loader.exec_module(mod)
    out = mod.main(["--quick", "--quiet", "--workers", "2", "--out", str(tmp_path)])
    for p in out["paths"]:
        assert Path(p).stat().st_size > 0
    with open(out["paths"][0]) as fh:
        rows = list(csv.DictReader(fh))
    assert {r["surrogate"] for r in rows} == set(mod.SURROGATES)
    training = {c.label for c in mod.QUICK_TRAINING}
    fitted = [r for r in rows if r["surrogate"] != "lumped (unfitted)"]
    # held out exactly when the fit did not train on it, and most of the grid is held out
    assert all((r["held_out"] == "True") == (r["condition"] not in training) for r in fitted)
    assert sum(r["held_out"] == "True" for r in fitted) > 0.7 * len(fitted)
    assert all(r["held_out"] == "True" for r in rows if r["surrogate"] == "lumped (unfitted)")
    assert {s["surrogate"] for s in out["summary"]} == set(mod.SURROGATES)
