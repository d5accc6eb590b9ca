"""Alternatives the data cannot tell apart from a kept entry, and the test that would.

A kept entry's round may hold a rival of another entry that fits nearly as well: the
tie-break (rounds._tie_break) refits the close ones at twice the elements and keeps the
lowest BIC, but where the rival also explains the data the choice rests on a fraction of
a noise. A stiffness at three voltages and one load (unipolar pulses, lab rig, truth
k = 59.9 N/m) lost to a nominal t_lz at N = 161: 1.86 um training against 1.98 um (1.70
um noise) - both move the stroke up with the voltage alike, and the rig's own errors (a
0.2 % monitor gain) are of that size. Reported as one answer, that is a coin toss
presented as a finding.

For each kept entry (a plain parameter: the law entries' forms change the law, not a
value) whose tie-break held a rival of another entry within ALT_RATIO of its worst error
(held out or training, at the tie's N): the final model is refitted at its N with the
entry swapped for the rival (the entry's values back at the baseline's, the rival's from
its tie refit; RES_NFEV evaluations), and where that swap still explains the data
(within ALT_RATIO of the final model's worst error and below UNEXPLAINED noises) it is an
alternative: reported beside the entry with the condition, among the tested voltages and
the loads from half the lightest to 1.5x the heaviest, where the two models' strokes
differ most - the recording that would tell them apart.
"""
from __future__ import annotations

import warnings

import numpy as np

from .catalog import NOMINAL, PHYSICS, _no_change
from .fit import fit
from .rules import RES_NFEV, UNEXPLAINED, _at_nominal, _spec, _um, _worst_error, _worst_rec, _worst_um

ALT_RATIO = 1.25     # a rival within this factor of the kept model's worst error explains the data as well
TELLS = 3.0          # a condition tells two models apart when their strokes differ by this many noises (RMS)
STEP = 10            # the separating runs sample every STEP-th point of a recording


def alternatives(dataset, D, executor, say, holdout) -> list:
    """The alternatives to D's kept entries (module docstring): [{entry, rival, N,
    kept: {train_rmse, heldout_rmse, values}, alternative: {...}, separate_at: {voltage,
    force, rms_difference, noise_ratio, tested, tells}}]; entries whose swap could not
    run or does not explain the data are left out."""
    out, rivals = [], []
    by_key = {e.key: e for e in PHYSICS + NOMINAL}
    for e in D.kept:
        tie = _tie_of(D, e.key)
        if tie is None or e.prepare is not _no_change:
            continue
        for key in [k for k in tie if k not in ("N", "kept", e.key)]:
            r = by_key.get(key)
            if r is None or r.prepare is not _no_change or any(k.name == r.name for k in D.kept):
                continue
            if _worst_rec(tie[key]) > ALT_RATIO * _worst_rec(tie[e.key]):
                continue
            swapped = _swap(dataset, D, e, r, tie[key], tie["N"], holdout, executor, say)
            if swapped is not None:
                out.append(swapped[0])
                rivals.append(swapped[1])
    # the final model is run once per condition for every alternative
    for rec, sep in zip(out, separating_conditions(dataset, D.final.params, rivals, D.final.sigma)):
        rec["separate_at"] = sep
        say(f"{rec['rival']} explains the data as well as {rec['entry']}"
            + (f": a recording at {sep['voltage'] / 1e3:g} kV against {sep['force']:g} N would tell them apart "
               f"({sep['noise_ratio']:.1f} noises)" if sep and sep["tells"] else ""))
    return out


def _tie_of(D, key):
    """The tie-break record of the round that kept `key` (the last such round), or None."""
    for ev in reversed(D.rounds):
        t = (ev.get(key) or {}).get("tie")
        if t and t.get("kept") == key:
            return t
    return None


def _swap(dataset, D, e, r, rival, N_tie, holdout, executor, say):
    """The final model with entry e swapped for rival r (its tie record `rival`), refitted
    at the final N: (the alternative's record without `separate_at`, its fitted
    Parameters), or None (module docstring)."""
    f, ctx = D.final, D.context
    start = {fp.key: rival["values"][fp.key] for fp in r.spec(f.params, ctx) if fp.key in rival.get("values", {})}
    pr = _at_nominal(f.params, [e], D.baseline.params, ctx).replace(**start)
    others = [k for k in D.kept if k is not e]
    say(f"{e.key} and {r.key} fitted alike at N = {N_tie}: {r.key} in its place refitted at N = "
        f"{f.params.N}")
    try:
        g = fit(dataset, _spec(pr, ctx, [*others, r]), base=pr, holdout=holdout, executor=executor, warm=f,
                max_nfev=RES_NFEV)
    except Exception as exc:       # the swapped model cannot run: no alternative to report
        say(f"{r.key} in place of {e.key} could not be fitted ({type(exc).__name__}: {exc})")
        return None
    w, wf = _worst_error(g), _worst_error(f)
    if w > ALT_RATIO * wf or w >= UNEXPLAINED * g.sigma:
        say(f"{r.key} in place of {e.key} leaves {_um(w)} against {_um(wf)}: not an alternative")
        return None
    say(f"{r.key} in place of {e.key} leaves {_um(w)} against {_um(wf)}: an alternative")
    return {"entry": e.key, "rival": r.key, "N": f.params.N,
            "kept": _summary(f, e.spec(f.params, ctx)), "alternative": _summary(g, r.spec(g.params, ctx))}, g.params


def _summary(f, spec) -> dict:
    return {"train_rmse": f.train_rmse, "heldout_rmse": f.heldout_rmse,
            "values": {fp.key: f.values[fp.key] for fp in spec}}


def separating_conditions(dataset, pa, pbs, sigma) -> list:
    """For each of the models pbs, the condition where it and model pa differ most (RMS
    stroke over a recording of the dataset's drive): each tested voltage (its first
    recording's protocol and time grid) against the tested loads, half the lightest and
    1.5x the heaviest; pa is run once per condition. Each: {voltage, force,
    rms_difference (m), noise_ratio, tested, tells}, or None when no run succeeded."""
    from dfa_model import simulate
    conds = dataset.conditions()            # (V, F) -> its recordings
    by_V = {}
    for (V, F), recs in sorted(conds.items()):
        by_V.setdefault(V, recs[0])
    loads = sorted({F for _, F in conds})
    trial = sorted(set(loads) | {round(0.5 * loads[0], 3), round(1.5 * loads[-1], 3)})
    best = [None] * len(pbs)
    if not pbs:
        return best

    def stroke(p, rec, F, t):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return simulate(p, rec.protocol, load=F, t_eval=t, warn=False).trace(t)
    for V, rec in by_V.items():
        t = rec.t[::STEP]
        for F in trial:
            if F <= 0:
                continue
            try:
                xa = stroke(pa, rec, F, t)
            except Exception:      # a condition the kept model cannot run: not a test to propose
                continue
            for i, pb in enumerate(pbs):
                try:
                    d = float(np.sqrt(np.mean((xa - stroke(pb, rec, F, t)) ** 2)))
                except Exception:  # nor one the rival cannot run
                    continue
                if np.isfinite(d) and (best[i] is None or d > best[i]["rms_difference"]):
                    best[i] = {"voltage": float(V), "force": float(F), "rms_difference": d,
                               "noise_ratio": d / sigma, "tested": (V, F) in conds, "tells": d >= TELLS * sigma}
    return best

def values_text(vals) -> str:
    """An entry's own values, as the report gives them (rho_l, the baseline's, left out)."""
    return ", ".join(f"{k} = {v:.4g}" for k, v in vals.items() if k != "rho_l")


def separate_text(sep) -> str:
    """Where the two models of an alternative differ most, in words."""
    if not sep:
        return "no run of the dataset's drive at another load told them apart"
    where = f"{sep['voltage'] / 1e3:.3g} kV against {sep['force']:.3g} N"
    if not sep["tells"]:
        return (f"no tested voltage at loads of half the lightest to 1.5x the heaviest tells them apart (at most "
                f"{sep['rms_difference'] * 1e6:.3g} um RMS, {sep['noise_ratio']:.1f} noises, at {where})")
    return (f"a recording at {where}{' (a tested condition)' if sep['tested'] else ''} would tell them apart (their "
            f"strokes differ by {sep['rms_difference'] * 1e6:.3g} um RMS there, {sep['noise_ratio']:.1f} noises)")


def phrases(D) -> list:
    """Each kept entry a rival explains the data as well as, and the recording that would
    tell them apart: the conclusion's and improved.toml's clauses."""
    return [f"{a['rival']} ({values_text(a['alternative']['values'])}) in place of {a['entry']} "
            f"({values_text(a['kept']['values'])}) fits these data as well ({_worst_um(a['alternative'])} against "
            f"{_worst_um(a['kept'])}): {separate_text(a['separate_at'])} (alternatives)"
            for a in getattr(D, "alternatives", None) or []]
