"""The improved model as a file: `dfa diagnose DATASET --out DIR` writes DIR/improved.toml,
a complete parameter file of the model the diagnosis ends with (README, 'Diagnosis';
contract in the architecture notes, 'Improved model'), and DIR/protocols/<recording>.toml,
the protocol each recording was read as.

improved.toml is the fitted model's parameters (Parameters.to_toml: every key, every number
exact) with provenance in comments: the dataset, the held-out errors, the missing physics
found, and for every value the diagnosis moved, its standard error and the nominal value
it replaces. With nothing held out (one condition) no nominal value is corrected and no
physics added: the values the training fit alone suggests are comments, the nominal values
stay. It holds no fit-internal setting (the fits' own tolerance is applied per run,
never stored in the parameters): N, scheme and rtol are the dataset's (N raised when the
resolution check found the mismatch to be the model's discretization). It runs unchanged
wherever a parameter file does (`dfa simulate --params`, `reduce`, `design`, `hold`,
`fmu build`); an edit that makes it inconsistent is the parameter file's one-line error.
"""
from __future__ import annotations

import datetime
import math
from pathlib import Path

from dfa_model.io.fileio import write_text_atomic
from dfa_model.io.parameters import applies
from dfa_model.waveforms import Protocol

from .alternatives import phrases as alternative_phrases
from .rules import _worst_um

NAME = "improved.toml"
PROTOCOLS = "protocols"


def _g(v) -> str:
    return f"{v:.6g}" if isinstance(v, float) else str(v)


def _nom(v) -> str:
    return "not in the nominal model" if v is None else f"nominal {_g(v)}"


# keys a law carries along with the fitted level without fitting them (catalog): none since
# Eq. (21)'s floor is fitted
CARRIED: dict = {}


def _unfitted(k: str, final) -> str | None:
    """Why a moved key has no standard error of its own, in words (None: it was fitted)."""
    if k in CARRIED and final.law == "linear":
        return CARRIED[k]
    if k == "rho_l" and final.law == "linear":
        return ("takes no part under law 'linear' (m_rho, q_rho and rho_min set the resistivity): the constant "
                "law's level fitted before Eq. (21) was added")
    return None


def fitted_keys(D) -> dict:
    """{model key: {value, stderr, nominal}} of every key the diagnosis moved from the
    nominal actuator (the fitted resistivity, the kept entries' parameters, corrected
    nominal values); stderr 0 for a key a chosen law's form sets without fitting it."""
    nominal, final = D.dataset.params, D.final.params
    nd, fd = nominal.to_dict(), final.to_dict()
    changed = []
    for table, keys in fd.items():
        if not isinstance(keys, dict):
            continue
        for k, v in keys.items():
            if nd.get(table, {}).get(k) != v:
                changed.append(k)
    numeric = [k for k in changed if not isinstance(getattr(final, k), str)]
    errs = D.final.model_values(numeric) if numeric and D.final.cov_z is not None else \
        {k: {"value": float(getattr(final, k)), "stderr": math.nan} for k in numeric}
    out = {}
    for k in changed:
        nom = getattr(nominal, k) if applies(nominal, k) else None
        if k in errs:
            out[k] = {"value": errs[k]["value"], "stderr": errs[k]["stderr"], "nominal": nom}
        else:
            out[k] = {"value": getattr(final, k), "stderr": None, "nominal": nom}
    return out


def improved_toml(D, dataset_name: str | None = None) -> str:
    """The text of improved.toml (module docstring)."""
    from dfa_model import __version__
    fk = fitted_keys(D)
    um = lambda x: "-" if x is None else f"{x * 1e6:.3g} um"   # noqa: E731
    when = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    found = [e for e in D.kept if e.kind == "physics"]
    corrected = [e.name.split(":", 1)[1] for e in D.kept if e.kind == "nominal"]
    head = [f"improved model written by dfa diagnose (dfa-toolkit {__version__}, {when})",
            f"dataset: {dataset_name or D.dataset.folder} ({len(D.dataset.recordings)} recordings, "
            f"{len(D.dataset.conditions())} conditions); nominal parameters: its actuator.toml",
            f"held-out stroke RMSE: baseline {um(D.baseline.heldout_rmse)}" +
            (f" -> improved {um(D.final.heldout_rmse)}" if D.improved else "") +
            f" (sensor noise {um(D.baseline.sigma)})",
            "missing physics found: " + (", ".join(e.key for e in found) if found else
                                         ("none verified" if any(e.kind == "physics" for e in
                                                                 getattr(D, "unverified", [])) else "none")
                                         + " (this is the baseline: the nominal actuator with its fitted resistivity)")]
    if corrected:
        head.append("nominal values corrected: " + ", ".join(corrected))
    if getattr(D, "unverified", None):
        head.append(f"nothing could be held out ({D.nothing_held_out()}): the nominal values are kept; the fit on the "
                    "training data alone suggests, unverified and not applied (report.json unverified_suggestions):")
        for e in D.unverified:
            if e.kind == "nominal":
                k = e.name.split(":", 1)[1]
                head.append(f"  suggested {k}: {_g(D.suggested.values[k])} +- {D.suggested.stderr[k]:.2g} "
                            f"(kept: nominal {_g(getattr(D.dataset.params, k))})")
            else:
                pars = entry_parameters(D, e, D.suggested)
                head.append(f"  suggested physics {e.key}: " + ", ".join(
                    f"{k} = {_g(v['value'])} +- {v['stderr']:.2g}" for k, v in pars.items()) + " (not added)")
    head += raised_phrases(getattr(D, "raised", None) or [])
    if again_phrase(D):
        head.append(again_phrase(D))
    head += alternative_phrases(D)
    r = getattr(D, "resolution", None)
    if r and r.get("resolution_only"):
        head.append(f"N raised from {r['N']} to {r['N_fine']}: {', '.join(r['dropped'])} only took up the model's "
                    f"discretization error")
    elif r and r.get("refined"):
        head.append(f"N raised from {r['N']} to {r['N_fine']}: the improved model fits better there "
                    f"({r['measure']} RMSE {r['kept_rmse'] * 1e6:.3g} -> {r['kept_fine_rmse'] * 1e6:.3g} um)")
    head.append("values the diagnosis moved (value +- standard error, nominal value replaced):")
    for k, f in fk.items():
        why = _unfitted(k, D.final.params)
        if why:
            head.append(f"  {k} = {_g(f['value'])} ({_nom(f['nominal'])}): {why}")
        elif f["stderr"] is None:
            head.append(f"  {k} = {f['value']!r} (nominal {f['nominal']!r}): the chosen form")
        elif f["stderr"] == 0:
            head.append(f"  {k} = {_g(f['value'])} ({_nom(f['nominal'])}): not a fitted coordinate (the "
                        "chosen form sets it, or does not use it)")
        else:
            head.append(f"  {k} = {_g(f['value'])} +- {f['stderr']:.2g} ({_nom(f['nominal'])})")
    body = []
    for line in D.final.params.to_toml().splitlines():
        key = line.split("=", 1)[0].strip() if "=" in line and not line.lstrip().startswith("#") else None
        f = fk.get(key)
        if f is not None and _unfitted(key, D.final.params):
            line += f"  [diagnosis: not fitted, see the header; {_nom(f['nominal'])}]"
        elif f is not None and f["stderr"]:
            line += f"  [diagnosis: +- {f['stderr']:.2g}, {_nom(f['nominal'])}]"
        elif f is not None:
            line += f"  [diagnosis: {_nom(f['nominal'])}]"
        body.append(line)
    return "\n".join(f"# {h}" for h in head) + "\n\n" + "\n".join(body) + "\n"


def write_improved(D, out: Path) -> str:
    """Write out/improved.toml; returns its name relative to out."""
    text = improved_toml(D)
    write_text_atomic(Path(out) / NAME, text)
    return NAME


def write_protocols(D, out: Path) -> dict:
    """Each recording's interpreted protocol (its voltage column read as stages, its force
    as the load) as a protocol file in out/protocols/: {recording: relative path}."""
    folder = Path(out) / PROTOCOLS
    folder.mkdir(parents=True, exist_ok=True)
    paths = {}
    for r in D.dataset.recordings:
        name = f"{r.name}.toml"      # r.name is its file's stem already: V6.5kV_F1N_r1 keeps its ".5..."
        Protocol(list(r.protocol.stages), load=r.load).save(
            folder / name, header=[f"the drive and load of recording {r.path.name} as dfa diagnose read them "
                                   f"(levels switched at the voltage's threshold crossings)",
                                   f"replay: dfa simulate --params {NAME} --protocol {PROTOCOLS}/{name}"])
        paths[r.name] = f"{PROTOCOLS}/{name}"
    return paths


NOTHING_KEPT = "(nothing kept)"   # a Diagnosis.raised step's `after` when the rounds kept nothing (resolution last)
RESELECTED = "(selection run again)"   # ... when the kept set's cut shrank at the finer N (resolution._reselect_due)
# ... when the final model's training error fell at the finer N (resolution._raise_training)
TRAINING = "(training error)"


def again_phrase(D) -> str | None:
    """What the resolution check again at a finer N did (diagnose._again)."""
    a = getattr(D, "again", None)
    if not a:
        return None
    s, r1, rec = a["self_error"], a["first"], a.get("check") or {}
    what = " + ".join(r1["missing_physics"] + r1["corrections"]) or "the baseline"
    off = (f"({what} at N = {r1['N_final']}) was {s['rmse'] * 1e6:.3g} um off its own solution at N = {s['N_ref']} "
           f"({s['ratio']:.1f}x the sensor noise)")
    if rec.get("refit"):       # no physics kept: the final model refitted at N_again
        head = f"the final model {off}"
        if rec.get("dropped"):
            how = "better" if rec["baseline_rmse"] < rec["rmse"] else "as well"
            return (f"{head}: at N = {a['N_again']} the baseline fits {how} ({rec['baseline_rmse'] * 1e6:.3g} um "
                    f"against {rec['rmse'] * 1e6:.3g} um with {', '.join(rec['dropped'])}, which cut the error by "
                    f"{rec['gain']:.0%} at N = {r1['N_final']} and {rec['gain_fine']:.0%} there): "
                    f"{', '.join(rec['dropped'])} only took up the model's discretization error and the final model "
                    f"is the baseline at N = {a['second']['N_final']} (diagnosed_again)")
        if a["taken"]:
            return (f"{head}: refitted at N = {a['N_again']} it fits better ({_worst_um(a['first'])} -> "
                    f"{_worst_um(a['second'])}); the final model is at N = {a['second']['N_final']} (diagnosed_again)")
        if rec.get("error"):
            return f"{head}, and its refit at N = {a['N_again']} could not run ({rec['error']}) (diagnosed_again)"
        return (f"{head}: refitted at N = {a['N_again']} it fits no better ({rec['rmse'] * 1e6:.3g} um): the first "
                f"outcome stands (diagnosed_again)")
    head = f"the resolution check again at N = {a['N_again']} (the dataset's {a['N_nominal']}): the final model {off}"
    dropped = (rec.get("dropped") or []) + (rec.get("dropped_marginal") or [])
    if rec.get("error"):
        return f"{head}, and the check could not run ({rec['error']}): the first outcome stands (diagnosed_again)"
    if dropped:
        return (f"{head}: {', '.join(dropped)} dropped there (it took up the model's discretization error); "
                f"the final model is at N = {a['second']['N_final']} (diagnosed_again)")
    if a["taken"]:
        return (f"{head}: {what} holds there and fits better; the final model is at N = {a['second']['N_final']} "
                f"(diagnosed_again)")
    return f"{head}: {what} holds there, and the finer model fits no better: the first outcome stands (diagnosed_again)"


def raised_phrases(raised: list) -> list:
    """What resolution first did (Diagnosis.raised), one phrase per run of steps: before
    the selection (the baseline's error) or after an entry was kept (the kept model's)."""
    out, i = [], 0
    while i < len(raised):
        j = i
        while j + 1 < len(raised) and raised[j + 1].get("after") == raised[i].get("after"):
            j += 1
        a, b, after = raised[i], raised[j], raised[i].get("after")
        if after == RESELECTED:
            out.append(f"N raised from {a['N']} to {a['N_fine']} after the selection kept "
                       f"{' + '.join(a['kept_first'])}: at N = {a['N_fine']} it removed {a['cut_ratio']:.0%} of the "
                       f"squared error it removed at N = {a['N']} and left {a['error'] * 1e6:.3g} -> "
                       f"{a['error_fine'] * 1e6:.3g} um, unexplained at both: the selection was run again there")
            i += 1
            continue
        when, whose = ("before the selection", "the baseline's") if after is None else \
            ("after the selection kept nothing (resolution last)", "the baseline's") \
            if after == NOTHING_KEPT else \
            ("for the trained conditions", "the final model's training") if after == TRAINING else \
            (f"after {after} was kept", "the kept model's")
        out.append(f"N raised from {a['N']} to {b['N_fine']} {when}: {whose} error {a['error'] * 1e6:.3g} -> "
                   f"{b['error_fine'] * 1e6:.3g} um (the model's own resolution, not missing physics)"
                   + (f"; {b['dropped']} dropped there: its gain did not hold at the finer N (it took up the "
                      f"model's discretization error)" if b.get("dropped") else ""))
        i = j + 1
    return out


def entry_parameters(D, e, f=None) -> dict:
    """A kept entry's parameters in the model's own keys ({key: {value, stderr}}): the
    fitted coordinates when they are keys, else (a law) the keys they set. f: the fit
    they come from (default the final model)."""
    f = D.final if f is None else f
    if e.shows:
        return f.model_values(e.shows(f.params) if callable(e.shows) else e.shows)
    keys = [fp.key for fp in e.spec(f.params, D.context)]
    return {k: {"value": f.values[k], "stderr": f.stderr[k]} for k in keys}
