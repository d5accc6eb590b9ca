"""The diagnosis written out: report.json (*contract*), report.md and its plots."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dfa_model.io.fileio import write_atomic, write_text_atomic

from .alternatives import phrases as alternative_phrases, separate_text, values_text
from .gain_account import PRIOR_SDS
from .improved import again_phrase, entry_parameters, raised_phrases, write_improved, write_protocols
from .levels import LEVEL_STEPS
from .rules import STRONG_ERROR, UNEXPLAINED, _um
from .timing import GAIN_PRIOR, TIMING

GAIN_LOUD = 2.0   # a monitor gain this many prior SDs off its condition's mean is named in the conclusion

HOLD_MIN = 2.0      # s: a hold (or one-polarity stretch) shorter than this keeps the charge near zero


def _fit_dict(f) -> dict | None:
    if f is None:
        return None
    return {"parameters": {k: {"value": v, "stderr": f.stderr[k]} for k, v in f.values.items()},
            "train_rmse": f.train_rmse, "heldout_rmse": f.heldout_rmse, "train": f.train, "heldout": f.heldout,
            "bic": f.bic, "aic": f.aic, "noise_rms": f.sigma, "wall_time": f.wall_time, "model_runs": f.runs,
            "notes": f.notes}


def _clean(o):
    if isinstance(o, dict):
        return {str(k): _clean(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean(v) for v in o]
    if isinstance(o, (np.floating, float)):
        return float(o) if math.isfinite(o) else None
    if isinstance(o, np.integer):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    return o


def to_json(D) -> dict:
    final = D.final if D.improved else None
    missing = []
    first = taken_rounds(D)[0]
    for i, e in enumerate(D.chain or D.kept):      # the round that kept it holds its evidence
        if e.kind != "physics" or e not in D.kept:
            continue
        missing.append({"name": e.name, "form": e.variant or None, "description": e.description,
                        "parameters": entry_parameters(D, e), "evidence": D.rounds[first + i][e.key]})
    corrected = {}
    nominal = D.dataset.params
    for k, v in D.final.values.items():
        if k in ("rho_l", "rho_ref") or any(e.kind == "nominal" and e.name == f"nominal:{k}" for e in D.kept):
            nom = getattr(nominal, "rho_l" if k == "rho_ref" else k)
            # corrected: the data move it beyond two standard errors of the fit
            corrected["rho_l" if k == "rho_ref" else k] = {
                "nominal": nom, "fitted": v, "stderr": D.final.stderr[k],
                "corrected": bool(abs(v - nom) > 2 * D.final.stderr[k]),
                # the resistivity is the baseline's own fitted parameter (fitted in every
                # diagnosis); a corrected nominal value has passed a held-out check
                "heldout_checked": D.held_out}
            if k == "rho_ref":
                corrected["rho_l"]["at_field"] = D.context.E_ref
    out = {
        "mismatch": bool(D.mismatch),
        "missing_physics": missing,
        "corrected_parameters": corrected,
        "located": [w.to_dict() for w in D.windows if w.systematic],
        "fit": {"baseline": _fit_dict(D.baseline), "improved": _fit_dict(final)},
        "conclusion": conclusion(D),
        "nothing_held_out": D.nothing_held_out(),
        "unverified_suggestions": unverified_suggestions(D),
        "unexplained": unexplained(D),
        "resolution": D.resolution,
        "values_in_N": getattr(D, "values_in_N", None),
        "resolution_first": D.raised,
        "reselect": getattr(D, "reselect", None),
        "cold_refit": getattr(D, "cold", None),
        "heldout_common_gain": getattr(D, "calibration", None),
        "gain_account": getattr(D, "gain_account", None),
        "self_error": getattr(D, "self_error", None),
        "diagnosed_again": getattr(D, "again", None),
        "alternatives": getattr(D, "alternatives", None) or None,
        "drive_timing": drive_timing(D) or None,
        "monitor_gain": monitor_gain(D) or None,
        "zeros_fitted": zeros_fitted(D) or None,
        "charge_hidden": charge_hidden(D) or None,
        "headline": headline(D),
        "trends": D.trends,
        # the constant rho_l each training voltage prefers on its own (levels.py: where the
        # field laws also start), at its field
        "voltage_levels": [{"field": E, "rho_l": rho} for E, rho in getattr(D.context, "levels", ())] or None,
        "candidates": D.rounds,
        "recordings": [{"recording": r.name, "voltage": r.hold_voltage, "force": r.force_mean,
                        "notes": r.notes, "rho_factor_baseline": D.baseline.rho_factors.get(r.name),
                        "offset_baseline": D.baseline.offsets.get(r.name)} for r in D.dataset.recordings],
        "wall_time": D.wall_time,
    }
    return _clean(out)


def unverified_suggestions(D) -> list:
    """report.json's `unverified_suggestions`: what the rounds kept when nothing was held
    out (diagnose.py, step 5), not applied to the final model or improved.toml. A nominal
    value: {name (its key), kind, nominal, suggested, stderr, reason, evidence}; physics:
    {name, kind, form, nominal ({key: the nominal model's value, None when it has no such
    key}), suggested ({key: value}), parameters ({key: {value, stderr}}), reason, evidence}."""
    from dfa_model.io.parameters import applies
    out = []
    why = D.nothing_held_out()
    chain = D.chain or []
    for e in D.unverified:
        ev = D.rounds[taken_rounds(D)[0] + chain.index(e)][e.key] if e in chain else {}
        reason = (f"nothing could be held out ({why}): kept on the training data alone (delta BIC "
                  f"{ev.get('delta_bic', float('nan')):+.1f}), never checked on data it was not fitted to; "
                  f"not applied")
        if e.kind == "nominal":
            k = e.name.split(":", 1)[1]
            out.append({"name": k, "kind": "nominal", "nominal": getattr(D.dataset.params, k),
                        "suggested": D.suggested.values[k], "stderr": D.suggested.stderr[k], "reason": reason,
                        "evidence": ev})
        else:
            pars = entry_parameters(D, e, D.suggested)
            nd = D.dataset.params
            out.append({"name": e.name, "kind": "physics", "form": e.variant or None,
                        "nominal": {k: (getattr(nd, k) if applies(nd, k) else None) for k in pars},
                        "suggested": {k: v["value"] for k, v in pars.items()}, "parameters": pars,
                        "reason": reason, "evidence": ev})
    return out


def _suggestion_names(D) -> str:
    return ", ".join(e.name.split(":", 1)[1] if e.kind == "nominal" else e.key for e in D.unverified)


def hold_speed(t, x, t0, t1, span=0.5) -> float:
    """Average unzipping speed over the hold [t0, t1] (m/s, positive when unzipping): the
    drop between the mean strokes of its first and last `span` s over the time between
    their centres (the Sec. 3.1 peak-to-end drop, robust to sensor noise)."""
    a = (t >= t0) & (t < t0 + span)
    b = (t > t1 - span) & (t <= t1)
    return float((np.mean(x[a]) - np.mean(x[b])) / (t1 - t0 - span))


def headline(D) -> list:
    """Per condition, the paper's headline metric (hold_speed): measured mean, the
    repetitions' own SD, and the baseline's and the improved model's error. The spread a
    mismatch must hide in is the repetition scatter pooled over all conditions (relative:
    it comes from the device's rho_l spread, common to every condition; a per-condition
    SD of two or three repetitions is too rough to judge by), times the condition's
    speed. Concealed: the baseline's error lies within it. A condition whose hold (after
    its reset) is shorter than HOLD_MIN has no row: a polarity inversion throughout reads
    as a reset with a hold of a few ms, where a speed means nothing."""
    rows, rel = [], []
    for c, recs in D.dataset.conditions().items():
        t0, t1 = recs[0].reset_end, recs[0].duration
        if t1 - t0 < HOLD_MIN:
            continue
        meas = [hold_speed(r.t, r.stroke, t0, t1) for r in recs]
        base = [hold_speed(r.t, D.baseline.simulated[r.name], t0, t1) for r in recs]
        row = {"voltage": c[0], "force": c[1], "repetitions": len(recs), "speed_measured": float(np.mean(meas)),
               "speed_sd_condition": float(np.std(meas, ddof=1)) if len(recs) > 1 else None,
               "speed_error_baseline": float(np.mean(base) - np.mean(meas))}
        if D.improved:
            imp = [hold_speed(r.t, D.final.simulated[r.name], t0, t1) for r in recs]
            row["speed_error_improved"] = float(np.mean(imp) - np.mean(meas))
        if len(recs) > 1 and row["speed_measured"] != 0:
            rel += list((np.asarray(meas) - np.mean(meas)) / abs(np.mean(meas)))
            rel.append(None)    # condition boundary: its mean was estimated (one dof)
        rows.append(row)
    # pooled relative SD: sum of squares over (n_i - 1) degrees of freedom per condition
    ss, dof, group = 0.0, 0, []
    for v in rel + [None]:
        if v is None:
            if group:
                ss += float(np.sum(np.square(group)))
                dof += len(group) - 1
            group = []
        else:
            group.append(v)
    pooled = math.sqrt(ss / dof) if dof > 0 else None
    for row in rows:
        row["speed_spread"] = None if pooled is None else pooled * abs(row["speed_measured"])
        row["concealed"] = None if pooled is None else bool(abs(row["speed_error_baseline"]) <= row["speed_spread"])
    return rows


def conclusion(D) -> str:
    """One sentence: what was found, and whether it explains the data. "No missing
    physics found" only when the baseline reaches the noise; a final model that leaves
    UNEXPLAINED sensor noises or more is an unexplained mismatch, whatever was kept."""
    phys = [e.key for e in D.missing_physics]
    corr = [e.name.split(":", 1)[1] for e in D.corrections]
    parts = []
    if D.unexplained:
        rmse, kind = D.unexplained_by
        who = "the final model (the baseline: no change verified)" if D.unverified else "the best model"
        held = D.final.heldout_rmse
        also = (f" (held out {held * 1e6:.3g} um: the held-out condition lies between the trained ones)"
                if kind == "training" and held is not None else "")
        parts.append(f"unexplained mismatch: {who} leaves a {kind} stroke RMSE of {rmse * 1e6:.3g} um, "
                     f"{rmse / D.final.sigma:.1f}x the sensor noise{also}")
        if phys:
            parts.append("missing physics found, explaining part of it: " + ", ".join(phys))
        calibration = calibration_phrase(D)
        if calibration:
            parts.append(calibration)
    elif phys:
        parts.append("missing physics: " + ", ".join(phys))
    elif any(e.kind == "physics" for e in D.unverified):
        parts.append("no missing physics verified")
    else:
        parts.append("no missing physics found")
    if (gp := gain_account_phrase(D)):
        parts.append(gp)
    parts += alternative_phrases(D)
    if (sp := self_error_phrase(D)):
        parts.append(sp)
    if (ap := again_phrase(D)):
        parts.append(ap)
    parts += raised_phrases(D.raised)
    if reselect_phrase(D):
        parts.append(reselect_phrase(D))
    timed = drive_timing(D)
    if timed:
        parts.append(f"the drive's timing was fitted with the model in {len(timed)} of {len(D.dataset.recordings)} "
                     f"recordings (their drives' switches or hold starts, read off the voltage record to within a "
                     f"sample: drive_timing)")
    off = {r: g for r, g in monitor_gain(D).items() if abs(g) >= GAIN_LOUD * GAIN_PRIOR}
    if off:
        lo, hi = min(off.values()), max(off.values())
        parts.append(f"the voltage monitor read {len(off)} recording(s) {lo:+.2%}" + (f" to {hi:+.2%}" if hi > lo else "")
                     + f" off its condition's other repetitions (its gain, fitted with the model: monitor_gain; "
                     f"prior SD {GAIN_PRIOR:.1%}): check its calibration, or what else differs between those "
                     f"repetitions (the gains take up any force the model misses in one of them)")
    r = D.resolution
    if r and r.get("resolution_only"):
        parts.append(f"{', '.join(r['dropped'])} only took up the model's discretization error (it cut the "
                     f"{r['measure']} error by {r['gain']:.0%} at N = {r['N']}, by {r['gain_fine']:.0%} at "
                     f"N = {r['N_fine']}{_first_check(r)}): the data ask for a finer N, not this entry")
    elif r and r.get("refined"):
        gone = [m for m in r.get("marginal", []) if m["dropped"] and not m.get("later")]
        later = [m for m in r.get("marginal", []) if m["dropped"] and m.get("later")]
        for m in later:
            at = m.get("N_check", r["N_fine"])
            parts.append(f"{m['entry']} dropped: on top of the entries kept after it it cut the {r['measure']} error "
                         f"by {m['gain_fine']:.0%} at N = {at}, short of acceptance: they explain what it took up"
                         + (f" (the final model is the rest at N = {at})" if at != r["N_fine"] else ""))
        if gone:
            cuts = ", ".join(f"{m['entry']} cut the {r['measure']} error by {m['gain']:.0%} on top of the rest at "
                             f"N = {r['N']}, by {m['gain_fine']:.0%} at N = {m.get('N_check', r['N_fine'])}"
                             for m in gone)
            parts.append(f"{', '.join(m['entry'] for m in gone)} dropped ({cuts}): it took up the model's "
                         f"discretization error, not physics; the final model is the rest at N = "
                         f"{r.get('N_final', r['N_fine'])}")
        elif not later:
            parts.append(f"the final model is at N = {r['N_fine']} (N = {r['N']} left its own discretization error: "
                         f"{r['kept_rmse'] * 1e6:.3g} um {r['measure']} RMSE against "
                         f"{r['kept_fine_rmse'] * 1e6:.3g} um{_first_check(r)})")
    if (vp := values_phrase(D)):
        parts.append(vp)
    # after the resolution's phrases: their errors are the warm refits' the cold one started from
    c = getattr(D, "cold", None)
    if c and c["taken"]:
        parts.append(f"the final model was refitted at N = {c['N']} from neutral per-recording nuisances (the warm "
                     f"starts across N had carried the coarser fits' values): {c['measure']} RMSE "
                     f"{c['rmse'] * 1e6:.3g} -> {c['rmse_cold'] * 1e6:.3g} um (cold_refit)")
    blind = zeros_fitted(D)
    if blind and len(blind) == len(D.dataset.recordings) and "stiffness" not in phys:
        parts.append(f"the sensor zeros were fitted in all {len(blind)} recordings (the model never rests on its "
                     f"stop in them), and they take up a constant stroke offset: a stiffness is hard to tell from "
                     f"them - record a rest stretch at 0 V before the drive (zeros_fitted)")
    hidden = charge_hidden(D)
    charge_physics = {"field_dependent_resistivity", "polarization_branch"}
    if hidden and len(hidden) == len(D.dataset.recordings) and not charge_physics & {e.name for e in D.kept}:
        parts.append(f"no recording holds one polarity for {HOLD_MIN:g} s or more: the interface charge stays near "
                     f"zero, so a field-dependent resistivity or a polarization branch hardly shows in the stroke - "
                     f"record a DC hold (the paper's reset + hold) to test for them (charge_hidden)")
    if corr:
        parts.append("nominal value(s) corrected: " + ", ".join(corr))
    if D.unverified:
        kinds = {e.kind for e in D.unverified}
        nots = {frozenset({"nominal"}): "not corrections", frozenset({"physics"}): "not missing physics"}.get(
            frozenset(kinds), "neither corrections nor missing physics")
        parts.append(f"nothing could be held out ({D.nothing_held_out()}): {_suggestion_names(D)} listed as "
                     f"unverified suggestions, {nots} (with them the training stroke RMSE would be "
                     f"{D.suggested.train_rmse * 1e6:.3g} um; not checked on data they were not fitted to)")
    elif not D.held_out:
        parts.append(f"nothing could be held out ({D.nothing_held_out()})")
    return "; ".join(parts)


def self_error_phrase(D) -> str | None:
    """The final model's own discretization error at its fitted values (self_error.py),
    when it reaches the noise: the named values carry the grid's bias."""
    s = getattr(D, "self_error", None)
    if not s or not s["flagged"]:
        return None
    fine = (f", {s['rmse_fine'] * 1e6:.3g} um at N = {s['N_fine']}" if s.get("rmse_fine") is not None else "")
    return (f"the final model is {s['rmse'] * 1e6:.3g} um off its own solution at N = {s['N_ref']} at its fitted "
            f"values (N = {s['N']}, {s['ratio']:.1f}x the sensor noise{fine}): its values carry the grid's bias - "
            f"diagnose again with a finer N in the dataset's actuator file, unless the data were made by this "
            f"model at N = {s['N']} (self_error)")


def gain_account_phrase(D) -> str | None:
    """What the training conditions' monitors' common gains make of a kept stiffness
    (gain_account.py), when they fit the training recordings as well: the recordings cannot
    tell the two apart."""
    a = getattr(D, "gain_account", None)
    if not a or "error" in a or a["separable"]:
        return None
    gains = ", ".join(f"{c['gain']:+.2%} at {c['voltage'] / 1e3:.3g} kV, {c['force']:.3g} N" for c in a["conditions"])
    sd = min(c["prior_sd"] for c in a["conditions"])
    need = max(abs(c["gain"]) for c in a["conditions"])
    which = " and ".join(a["entries"])
    if a.get("dropped"):
        return (f"{which} dropped: the resolution check kept it on the training recordings alone (the held-out "
                f"condition near the noise), and without it each training condition's monitor reading off by a "
                f"common gain ({gains}; prior SD {sd:.2%} or more) fits them as well ({a['train_rmse'] * 1e6:.3g} um "
                f"against {a['train_rmse_kept'] * 1e6:.3g} um) - with the monitors calibrated to better than "
                f"{need:.2%}, or another condition held out, the data would tell (gain_account)")
    return (f"{which} cannot be told from the voltage monitors' calibration in these recordings: the final model "
            f"without it, each training condition's monitor reading off by a common gain ({gains}; prior SD "
            f"{sd:.2%} or more), fits them as well ({a['train_rmse'] * 1e6:.3g} um against "
            f"{a['train_rmse_kept'] * 1e6:.3g} um) - with the monitors calibrated to better than {need:.2%}, or more "
            f"conditions recorded, the data would tell (gain_account)")


def alternatives_lines(alts) -> list:
    """report.md's section on the alternatives (alternatives.py)."""
    if not alts:
        return []
    L = ["", "## Alternatives these data cannot tell apart", "",
         "A rival of another entry fitted nearly as well in the round that kept the entry; swapped in for it and "
         "refitted, it explains the data as well. The choice between them rests on a fraction of a noise:", "",
         "| kept entry | its values | rival | its values | kept: train / held out (um) | rival: train / held out (um) "
         "| what would tell them apart |",
         "|---|---|---|---|---|---|---|"]
    um = (lambda x: "-" if x is None else f"{x * 1e6:.3g}")
    for a in alts:
        k, r = a["kept"], a["alternative"]
        L.append(f"| {a['entry']} | {values_text(k['values'])} | {a['rival']} | {values_text(r['values'])} | "
                 f"{um(k['train_rmse'])} / {um(k['heldout_rmse'])} | {um(r['train_rmse'])} / {um(r['heldout_rmse'])} "
                 f"| {separate_text(a['separate_at'])} |")
    return L


def gain_account_lines(a) -> list:
    """report.md's section on a kept stiffness against the training conditions' monitors'
    common gains (gain_account.py)."""
    if not a:
        return []
    which = " and ".join(a["entries"])
    L = ["", f"## {which} against the voltage monitors' calibration", ""]
    if "error" in a:
        return L + [f"The final model without {which}, with each condition's common monitor gain free, could not be "
                    f"fitted ({a['error']})."]
    L += [f"At each condition a stiffness is nearly a constant force, and so is a voltage monitor reading off by a "
          f"common gain (the Maxwell force scales as (1 + g)^2). The final model without {which}, refitted at "
          f"N = {a['N']} with each training condition's common gain free (the per-recording prior on the "
          f"recordings' mean):", "",
          "| condition | common gain | prior SD |", "|---|---|---|"]
    L += [f"| {c['voltage'] / 1e3:.3g} kV, {c['force']:.3g} N | {c['gain']:+.3%} | {c['prior_sd']:.2%} |"
          for c in a["conditions"]]
    why = " (they fit the training recordings worse)" if not a["fits_as_well"] else f" (beyond {PRIOR_SDS:g} prior SDs)"
    verdict = ("The recordings cannot tell the two apart: calibrate the monitors to better than the gains above, or "
               "record more conditions." if not a["separable"] else f"The gains do not stand in for it{why}: {which} "
               "stands.")
    if a.get("dropped"):
        verdict += (f" The resolution check had kept {which} on the training recordings alone (the held-out "
                    f"condition near the noise): it is dropped, and the final model is the rest refitted without it.")
    return L + ["", f"Training RMSE {a['train_rmse'] * 1e6:.3g} um against {a['train_rmse_kept'] * 1e6:.3g} um with "
                f"{which}. {verdict}"]


def calibration_phrase(D) -> str | None:
    """What the held-out monitors' common gain makes of the held-out error (diagnose.
    _calibration): whether a calibration within its prior (2 SDs) brings it within
    UNEXPLAINED noises where the same refit without it does not."""
    c = getattr(D, "calibration", None)
    if not c:
        return None
    conds = c["conditions"]
    gains = ", ".join(f"{x['gain']:+.2%} at {x['voltage'] / 1e3:.3g} kV, {x['force']:.3g} N (prior SD "
                      f"{x['prior_sd']:.2%})" for x in conds)
    sigma = D.final.sigma
    ratio, ratio0 = c["rmse"] / sigma, c["rmse_without"] / sigma
    within = all(abs(x["gain"]) <= 2 * x["prior_sd"] for x in conds)
    which = "condition's" if len(conds) == 1 else "conditions'"
    head = (f"refitted with the held-out {which} voltage monitors' common gain free ({gains}), the held-out RMSE is "
            f"{c['rmse'] * 1e6:.3g} um, {ratio:.1f}x the noise ({ratio0:.1f}x without it)")
    if ratio0 < UNEXPLAINED:
        return (head + ": the held-out recordings' own nuisances, refitted, already bring it within "
                f"{UNEXPLAINED:g} noises (heldout_common_gain)")
    if ratio < UNEXPLAINED and within:
        return (head + ": a calibration within its prior would account for the mismatch, and the training "
                "conditions cannot tell it from a force the model misses there - check the monitors' calibration, "
                "or hold out another condition (heldout_common_gain)")
    why = [w for w, bad in (("a gain beyond 2 prior SDs", not within), ("still unexplained", ratio >= UNEXPLAINED))
           if bad]
    return head + f" ({', '.join(why)}): not the monitors' calibration alone (heldout_common_gain)"


def taken_rounds(D) -> tuple:
    """(first, last + 1): the indices in D.rounds of the selection whose entries were kept
    (the rounds before it ran at a coarser N when nothing was kept there or when the
    selection was run again at a finer N; a selection run again and not taken follows it)."""
    return getattr(D, "taken", None) or (0, len(D.rounds))


def reselect_phrase(D) -> str | None:
    """What the selection run again at the finer N found, and which model was taken."""
    r = getattr(D, "reselect", None)
    if not r:
        return None
    first, second = " + ".join(r["first"]), " + ".join(r["second"]) or "nothing"
    N2 = f" (at N = {r['second_N']})" if r["second_N"] != r["N_fine"] else ""
    won = f"{second} taken" if r["kept"] == "second" else f"{first} stands"
    return (f"run again at N = {r['N_fine']}, the selection kept {second}{N2}: {r['measure']} RMSE "
            f"{r['second_rmse'] * 1e6:.3g} um, BIC {r['second_bic']:.1f}, against {first} refitted there at "
            f"{r['first_fine_rmse'] * 1e6:.3g} um, BIC {r['first_bic']:.1f}: {won} (the lower BIC)")


def tried(D) -> dict:
    """How far every tried entry got: per candidate, its best full fit over the rounds
    (held-out and training RMSE, BIC change against the model it extended), or, never
    fitted, its last screen (the BIC change and held-out ratio its first step predicted)
    and why it was not fitted."""
    out = {}
    for i, rnd in enumerate(D.rounds):
        for key, ev in rnd.items():
            if ev.get("fitted"):
                row = {"fitted": True, "round": i + 1, "heldout_rmse": ev["heldout_rmse"],
                       "train_rmse": ev["train_rmse"], "delta_bic": ev["delta_bic"]}
                if ev.get("stopped"):
                    row["stopped"] = ev["stopped"]
                if ev.get("late"):
                    row["late"] = True
                old = out.get(key)
                better = old is None or not old["fitted"] or (
                    (row["heldout_rmse"] if row["heldout_rmse"] is not None else row["train_rmse"])
                    < (old["heldout_rmse"] if old["heldout_rmse"] is not None else old["train_rmse"]))
                if better:
                    out[key] = row
            elif key not in out or not out[key]["fitted"]:
                sc = ev.get("screen") or {}
                why = ev.get("error") or ev.get("skipped") or "the screen did not shortlist it"
                out[key] = {"fitted": False, "round": i + 1, "predicted_delta_bic": sc.get("predicted_delta_bic"),
                            "predicted_heldout_ratio": sc.get("heldout_ratio"), "why": why}
    return out


def drive_timing(D) -> dict:
    """Each recording's drive timing as the final model fitted it (timing.TIMING's keys
    it has; the monitor's gain apart: monitor_gain)."""
    return {r: {k: v for k, v in tm.items() if k in TIMING} for r, tm in (D.final.timing or {}).items()
            if any(k in TIMING for k in tm)}


def monitor_gain(D) -> dict:
    """Each recording's voltage monitor gain as the final model fitted it, relative to its
    condition's mean (the drive the actuator saw is the read one over 1 + gain; only the
    differences between a condition's repetitions are a nuisance: diagnosis/timing.py)."""
    return {r: tm["gain"] for r, tm in (D.final.timing or {}).items() if "gain" in tm}


def values_phrase(D) -> str | None:
    """The conclusion's account of the kept entries' values over doublings of N
    (convergence.value_check), when they moved: None when they settled at the first
    doubling (or were not followed)."""
    v = getattr(D, "values_in_N", None)
    if v and v.get("refined"):
        a, b = [st["heldout_rmse"] if st["heldout_rmse"] is not None else st["train_rmse"] for st in v["steps"][-2:]]
        return (f"the named values settled at N = {v['steps'][-1]['N']}, where the kept model fits better "
                f"({_um(a)} -> {_um(b)}): the final model is at N = {v['N_final']} (values_in_N)")
    if not v or len(v["steps"]) < 2 or (v["converged"] and len(v["steps"]) == 2):
        return None
    Ns = ", ".join(str(st["N"]) + (" (one Gauss-Newton step)" if st.get("predicted") else "") for st in v["steps"])
    vals = "; ".join(f"{k} " + ", ".join(f"{st['values'][k]:.3g}" for st in v["steps"])
                     for k in list(v["steps"][0]["values"])[:3])
    if v["converged"]:
        return (f"the named values moved with the elements and settled ({vals} at N = {Ns}): the final model is at "
                f"N = {v['N_final']} (values_in_N)")
    if v.get("finer_worse"):
        return (f"the named values moved at a finer N ({vals} at N = {Ns}), but {v['stopped']}: the data do not ask "
                f"for it, and the final model is at N = {v['N_final']} (values_in_N)")
    return (f"the named values had not settled in N ({vals} at N = {Ns}; {v['stopped']}): the final model is at "
            f"N = {v['N_final']}, and a finer N may move them further (values_in_N)")


def zeros_fitted(D) -> list:
    """The recordings whose sensor zero the final model fitted instead of reading it at
    rest (fit.align: its stroke rests on the stop in fewer than REST_MIN samples). There
    the zero takes up a constant stroke offset, the main sign of a stiffness: on the lab
    rig under reset + hold a stiffness of 41.7 N/m was named with a 0.5 s rest stretch
    before the drive (held out 7.01 -> 3.15 um) and missed without one (2.35 um, 1.07
    noises: nothing to find); under unipolar pulses the stroke returns to the stop in
    every pause and the zero is read there."""
    from .fit import REST_MIN
    f = D.final
    out = []
    for r in D.dataset.recordings:
        sim = f.simulated.get(r.name)
        if sim is not None and np.count_nonzero(sim - f.offsets.get(r.name, 0.0) <= 0.0) < REST_MIN:
            out.append(r.name)
    return out


def longest_hold(r) -> float:
    """The longest stretch (s) over which recording r's drive, read off its voltage record
    (recordings._interpret: a pause's level is 0 exactly), keeps one polarity (consecutive
    stretches of one sign joined: a staircase is one)."""
    edges = np.concatenate([[0.0], r.switches, [r.duration]])      # as recordings._drive lays them
    best, start, sign = 0.0, 0.0, 0.0
    for a, b, v in zip(edges[:-1], edges[1:], r.levels):
        if np.sign(v) != sign:
            start, sign = a, np.sign(v)
        if sign:
            best = max(best, b - start)
    return float(best)


def charge_hidden(D) -> list:
    """The recordings whose drive never holds one polarity for HOLD_MIN s (a polarity
    inversion throughout): there the interface charge stays near zero and the charge's
    physics - a field law, a polarization branch - hardly moves the stroke. On the lab rig
    under a 1 Hz full inversion the trial's laws and slow branch left their baselines at
    1.1-1.2 noises held out and the proof's law and branch at the noise
    (docs/guide/diagnosis.md)."""
    return [r.name for r in D.dataset.recordings if longest_hold(r) < HOLD_MIN]


def unexplained(D) -> dict | None:
    """report.json's `unexplained`: None when the final model reaches the noise, else
    where (the final model's systematic windows), how large, and how far each tried
    entry got."""
    if not D.unexplained:
        return None
    rmse, kind = D.unexplained_by
    t = tried(D)
    return {"rmse": rmse, "measure": kind, "sensor_noise": D.final.sigma, "ratio": rmse / D.final.sigma,
            "model": " + ".join(["baseline"] + [e.key for e in D.kept]),
            "windows": [w.to_dict() for w in D.remaining_windows()], "tried": t,
            "training_only": training_only(t, D.final.sigma, D.final.heldout_rmse)}


def training_only(rows: dict, sigma: float, heldout: float | None) -> list:
    """The tried entries that reach the noise on the training conditions (within
    UNEXPLAINED noises) but predict the held-out ones worse than the final model does:
    the trained conditions do not determine them where the held-out ones lie. An Eq. (21)
    law under polarity inversion, its knee between the trained 6 and 8 kV and 7 kV held
    out: 1.77 um in training (1.4 noises), 8.38 um held out against the baseline's 4.79 (each
    recording probes one field there, so nothing pins the knee). [{candidate,
    train_rmse, heldout_rmse}], best held-out first."""
    if heldout is None:
        return []
    out = [{"candidate": k, "train_rmse": r["train_rmse"], "heldout_rmse": r["heldout_rmse"]}
           for k, r in rows.items() if r.get("fitted") and r.get("heldout_rmse") is not None
           and r["train_rmse"] < UNEXPLAINED * sigma and r["heldout_rmse"] > heldout]
    return sorted(out, key=lambda r: r["heldout_rmse"])


def _per_condition(D, row_height):
    """(pyplot, {condition: recordings}, figure, axes): one row per condition."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    conds = D.dataset.conditions()
    fig, axes = plt.subplots(len(conds), 1, figsize=(9, row_height * len(conds) + 0.8), sharex=True, squeeze=False)
    return plt, conds, fig, axes


def _finish(plt, fig, axes, path):
    # the legend above the panels, beside the title: inside one it covered the data
    fig.legend(*axes[0, 0].get_legend_handles_labels(), fontsize=8, loc="upper right", ncol=3, frameon=False)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout(rect=(0, 0, 1, 0.98))
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)


def plot_residuals(D, path):
    plt, conds, fig, axes = _per_condition(D, 1.9)
    for ax, (c, recs) in zip(axes[:, 0], conds.items()):
        for r in recs:
            ax.plot(r.t, D.baseline.residual(r) * 1e6, lw=0.5, color="C3", alpha=0.7)
            if D.improved:
                ax.plot(r.t, D.final.residual(r) * 1e6, lw=0.5, color="C2", alpha=0.7)
        held = " (held out)" if recs[0].name in D.baseline.heldout else ""
        ax.set_title(f"{c[0] / 1e3:g} kV, {c[1]:g} N{held}", fontsize=9, loc="left")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel("residual (µm)")
    axes[0, 0].plot([], [], color="C3", label="baseline")
    if D.improved:
        axes[0, 0].plot([], [], color="C2", label="improved")
    fig.suptitle("measured - model stroke, every recording", fontsize=10)
    _finish(plt, fig, axes, path)


def plot_overlays(D, path):
    plt, conds, fig, axes = _per_condition(D, 2.0)
    for ax, (c, recs) in zip(axes[:, 0], conds.items()):
        r = recs[0]
        # every curve less the best model's sensor zero: without a rest stretch a baseline far
        # off fits its zero far off too (0.42 mm on an Eq. (21) dataset), and the measured
        # stroke then showed the actuator at rest at -0.42 mm
        zero = D.final.offsets[r.name] if D.improved else D.baseline.offsets[r.name]
        ax.plot(r.t, (r.stroke - zero) * 1e3, lw=0.6, color="0.5", label="measured")
        ax.plot(r.t, (D.baseline.simulated[r.name] - zero) * 1e3, lw=1, color="C3", label="baseline")
        if D.improved:
            ax.plot(r.t, (D.final.simulated[r.name] - zero) * 1e3, lw=1, ls="--", color="C2", label="improved")
        ax.set_title(f"{r.name}" + (" (held out)" if r.name in D.baseline.heldout else ""), fontsize=9, loc="left")
        ax.set_ylabel("stroke (mm)")
    _finish(plt, fig, axes, path)


def plot_terms(D, path) -> bool:
    """The kept physics as curves with their uncertainty band (+-1 SE). False if none."""
    phys = D.missing_physics
    if not phys:
        return False
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from dfa_model.physics.kinematics import make
    fig, axes = plt.subplots(1, len(phys), figsize=(4.5 * len(phys), 3.4), squeeze=False)
    f = D.final
    for ax, e in zip(axes[0], phys):
        if e.name == "stiffness":
            x = np.linspace(0, make(f.params).x_e, 50)
            k, se = f.values["k"], f.stderr["k"]
            ax.plot(x * 1e3, k * x, color="C2")
            ax.fill_between(x * 1e3, (k - se) * x, (k + se) * x, color="C2", alpha=0.25)
            ax.set_xlabel("stroke (mm)")
            ax.set_ylabel("restoring force k x (N)")
            ax.set_title(f"stiffness k = {k:.3g} +- {se:.2g} N/m", fontsize=9)
        elif e.name == "field_dependent_resistivity":
            _plot_law(ax, f, D)
        elif e.name == "polarization_branch":
            chi, tau = f.values["chi_p"], f.values["tau_p"]
            t = np.linspace(0, 5 * tau, 100)
            lo, hi = _band(f, lambda p: p.chi_p * (1 - np.exp(-t / p.tau_p)))
            ax.plot(t, chi * (1 - np.exp(-t / tau)), color="C2")
            ax.fill_between(t, lo, hi, color="C2", alpha=0.25)
            ax.set_xlabel("time after a voltage step (s)")
            ax.set_ylabel("liquid's extra permittivity / eps_l")
            ax.set_title(f"polarization branch: chi_p = {chi:.3g} +- {f.stderr['chi_p']:.2g},\n"
                         f"tau_p = {tau:.3g} +- {f.stderr['tau_p']:.2g} s", fontsize=9)
        elif e.name == "series_resistance":
            from dfa_model.physics.equations import R_C
            from dfa_model.physics.model import DFAModel
            m = DFAModel(f.params.replace(R_s=0.0))
            cases = [(0.0, "-", "open (x = 0)"), (0.999 * make(f.params).x_e, "--", "zipped")]
            taus = [f.values["R_s"] * m.diagnostics(m.initial_state(x), 1000.0)[0][R_C] for x, _, _ in cases]
            t = np.linspace(0, 5 * max(taus), 200)     # long enough for the slower (zipped) charging
            for (x, ls, lab), tau in zip(cases, taus):
                ax.plot(t * 1e3, 1 - np.exp(-t / tau), ls=ls, color="C2", label=f"{lab}: R_s C = {tau * 1e3:.3g} ms")
            ax.set_xlabel("time after a voltage step (ms)")
            ax.set_ylabel("device voltage / source voltage")
            ax.legend(fontsize=8)
            ax.set_title(f"series resistance\nR_s = {f.values['R_s']:.3g} +- {f.stderr['R_s']:.2g} ohm", fontsize=9)
        else:
            pars = entry_parameters(D, e)
            ax.errorbar(range(len(pars)), [v["value"] for v in pars.values()], yerr=[v["stderr"] for v in pars.values()],
                        fmt="o")
            ax.set_xticks(range(len(pars)), list(pars))
            ax.set_title(e.name, fontsize=9)
    v = getattr(D, "values_in_N", None)
    s = getattr(D, "self_error", None)
    note = None
    # the bands are the fit's statistical errors: they say nothing of the values' move with N,
    # nor of the grid's bias the model's own error puts in them
    if v and not v["converged"] and not v.get("finer_worse") and len(v["steps"]) > 1:
        note = f"values not settled in N (fitted at N = {', '.join(str(st['N']) for st in v['steps'])}; values_in_N)"
    elif s and s["flagged"]:
        note = (f"the model at N = {s['N']} is {s['rmse'] * 1e6:.3g} um off its own solution at N = {s['N_ref']} "
                f"({s['ratio']:.1f}x the noise; self_error): the values carry the grid's bias")
    if note:
        fig.text(0.5, 0.01, note + ":\nthe bands are the fit's statistical errors only", ha="center", fontsize=7)
        fig.tight_layout(rect=(0, 0.09, 1, 1))
    else:
        fig.tight_layout()
    write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=110, format="png"))
    plt.close(fig)
    return True


def _band(f, quantity):
    """(lower, upper) one-SE band of quantity(params) from the fit's covariance (linearized
    in the fitted coordinates)."""
    from .model import apply
    z = np.asarray(f.z, float)
    y0 = np.asarray(quantity(f.params), float)
    J = []
    for i in range(len(z)):
        zp = z.copy()
        zp[i] += 1e-4
        J.append((np.asarray(quantity(apply(f.base, f.spec, zp)), float) - y0) / 1e-4)
    J = np.array(J)
    var = np.einsum("ij,ik,kj->j", J, f.cov_z, J) if f.cov_z is not None else np.zeros_like(y0)
    sd = np.sqrt(np.maximum(var, 0.0))
    return y0 - sd, y0 + sd


def _plot_law(ax, f, D):
    """The fitted resistivity law as a curve with its one-SE band, and the fields the
    recordings probe: the liquid's next to the front over the holds, from 80 % of the
    zipped field at the lowest hold voltage (it falls as the interface charges) to the
    zipped field at the highest - outside it the law is the form's extrapolation."""
    from dfa_model.physics.dielectrics import from_parameters

    from .model import zipped_field
    p = f.params
    V = [abs(r.hold_voltage) for r in D.dataset.recordings]
    probed = (0.8 * zipped_field(D.dataset.params, min(V)), zipped_field(D.dataset.params, max(V)))
    E_hi = max(p.E_hi if p.law == "spline" else 0.0, 1.5 * probed[1])
    E = np.geomspace(min(E_hi / 30, probed[0] / 3), E_hi, 160)
    rho = lambda q: from_parameters(q).rho(E)   # noqa: E731
    lo, hi = _band(f, lambda q: np.log(rho(q)))
    ax.axvspan(probed[0] / 1e6, probed[1] / 1e6, color="0.9", zorder=0, label="fields the recordings probe")
    ax.plot(E / 1e6, rho(p), color="C2", label="fitted law")
    ax.fill_between(E / 1e6, np.exp(lo), np.exp(hi), color="C2", alpha=0.25, label="one standard error")
    if p.law == "spline":
        E_k, r_k = from_parameters(p).knots
        ax.plot(E_k / 1e6, r_k, "o", color="C2", ms=4, label="knots")
    ax.axhline(D.dataset.params.rho_l, color="0.4", ls=":", lw=1, label="nominal rho_l (constant)")
    ax.legend(fontsize=7, loc="lower left")
    ax.set_xscale("log")
    ax.set_yscale("log")
    from matplotlib.ticker import NullFormatter
    ax.xaxis.set_minor_formatter(NullFormatter())    # a decade's minor labels overlap
    ax.set_xlabel("|E_l|, liquid field (MV/m)")
    ax.set_ylabel("ρ_l (Ω m)")
    ax.set_title("field-dependent resistivity: " + ("Eq. (21)" if p.law == "linear" else "monotone spline"),
                 fontsize=9)


def to_markdown(D, report: dict, plots: dict) -> str:
    um = lambda x: "-" if x is None else f"{x * 1e6:.3g}"   # noqa: E731
    L = [f"# Diagnosis of {D.dataset.folder.name}", "",
         f"**{report['conclusion']}.** {len(D.dataset.recordings)} recordings, "
         f"{len(D.dataset.conditions())} conditions; held out: "
         f"{', '.join(sorted(set(D.baseline.heldout))) or f'none ({D.nothing_held_out()})'}. Sensor noise from the "
         f"data: {D.baseline.sigma * 1e6:.3g} um RMS. Wall time {D.wall_time:.0f} s.", ""]
    if not D.held_out:
        L += [f"Nothing could be held out ({D.nothing_held_out()}): no nominal value is corrected and no physics "
              f"named, since no change was checked on data it was not fitted to; the final model is the baseline"
              + (f". What the fit on the training data alone would change ({_suggestion_names(D)}) is listed as "
                 f"unverified suggestions below." if D.unverified else "."), ""]
    L += ["## Before and after", "", "| model | train RMSE (um) | held-out RMSE (um) | BIC |", "|---|---|---|---|",
          f"| baseline (paper's model, rho_l fitted) | {um(D.baseline.train_rmse)} | {um(D.baseline.heldout_rmse)} | "
          f"{D.baseline.bic:.1f} |"]
    if D.suggested is not None:
        L.append(f"| + {_suggestion_names(D)} (unverified suggestion, not applied) | {um(D.suggested.train_rmse)} | "
                 f"- | {D.suggested.bic:.1f} |")
    if D.improved:
        what = " + ".join(e.name for e in D.kept)
        if D.final.params.N != D.baseline.params.N:
            what = (what + ", " if what else "") + f"N = {D.final.params.N}"
        L.append(f"| + {what} | {um(D.final.train_rmse)} | {um(D.final.heldout_rmse)} | {D.final.bic:.1f} |")
    if not report["headline"]:
        L += ["", f"Headline metric (average unzipping speed over the hold): none - no recording holds its voltage "
              f"for {HOLD_MIN:g} s after its drive's switches, and the paper's speed is read over such a hold."]
    else:
        L += ["", "Headline metric (average unzipping speed over the hold, um/s; spread: the repetitions' scatter, "
              "pooled over conditions as a fraction of the speed; concealed: the baseline's error within it):", "",
              "| condition | measured | spread | baseline error | improved error | concealed |",
              "|---|---|---|---|---|---|"]
    for h in report["headline"]:
        f = lambda v: "-" if v is None else f"{v * 1e6:+.3g}"   # noqa: E731
        sd = "-" if h["speed_spread"] is None else f"{h['speed_spread'] * 1e6:.3g}"
        hidden = "-" if h["concealed"] is None else ("yes" if h["concealed"] else "no")
        L.append(f"| {h['voltage'] / 1e3:g} kV, {h['force']:g} N | {h['speed_measured'] * 1e6:.3g} | {sd} | "
                 f"{f(h['speed_error_baseline'])} | {f(h.get('speed_error_improved'))} | {hidden} |")
    if report.get("unverified_suggestions"):
        L += ["", "## Unverified suggestions", "",
              f"Nothing could be held out ({D.nothing_held_out()}): these were kept on the training data alone and "
              f"never checked on data they were not fitted to. They are not corrections: the final model and "
              f"{report['improved_params']} keep the nominal values. Record another condition (another load or "
              f"voltage) to test them.", "",
              "| suggestion | nominal | suggested (+- standard error) | delta BIC (training) |", "|---|---|---|---|"]
        for u in report["unverified_suggestions"]:
            dbic = (u["evidence"] or {}).get("delta_bic")
            dbic = "-" if dbic is None else f"{dbic:+.1f}"
            if u["kind"] == "nominal":
                L.append(f"| {u['name']} | {u['nominal']:.4g} | {u['suggested']:.4g} +- {u['stderr']:.2g} | {dbic} |")
            else:
                nom = ", ".join(f"{k} = {'-' if v is None else f'{v:.4g}'}" for k, v in u["nominal"].items())
                sug = ", ".join(f"{k} = {v['value']:.4g} +- {v['stderr']:.2g}" for k, v in u["parameters"].items())
                form = f" ({u['form']})" if u["form"] else ""
                L.append(f"| {u['name']}{form} (physics) | {nom} | {sug} | {dbic} |")
    L += ["", f"The improved model as a parameter file: [{report['improved_params']}]({report['improved_params']}) "
          f"(`dfa simulate --params {report['improved_params']}`, `dfa reduce`, `dfa design`, `dfa hold`, "
          f"`dfa fmu build`); each recording's drive as a protocol file in `protocols/`.",
          "", "## Fitted parameters", "", "| parameter | nominal | fitted | standard error |", "|---|---|---|---|"]
    for k, v in D.final.values.items():
        L.append(f"| {k} | {getattr(D.dataset.params, k, '-')} | {v:.4g} | {D.final.stderr[k]:.2g} |")
    L += gain_account_lines(report.get("gain_account"))
    L += alternatives_lines(report.get("alternatives"))
    L += ["", "## Where the baseline misses", ""]
    sysw = [w for w in D.windows if w.systematic]
    if not sysw:
        L.append("No window of any recording shows a systematic mismatch (chi-square excess and runs test within "
                 "noise).")
    else:
        L += ["| recording | window | t (s) | RMS (um) | excess (SD) | runs (SD) | effect | signature |",
              "|---|---|---|---|---|---|---|---|"]
        for w in sysw:
            L.append(f"| {w.recording} | {w.name} | {w.t_start:.2f}-{w.t_end:.2f} | {w.rms * 1e6:.3g} | "
                     f"{w.excess:.1f} | {_runs_text(w.runs)} | {w.effect:.1f} | {w.signature} |")
    for s in D.trends:
        L.append(f"- {s}")
    lv = report.get("voltage_levels")
    if lv:
        L.append(f"- Fitted alone (a grid of {LEVEL_STEPS} per decade), each training voltage prefers a constant "
                 "rho_l of "
                 + ", ".join(f"{v['rho_l']:.2g} ohm m at {v['field']:.3g} V/m" for v in lv)
                 + f": a spread of {max(v['rho_l'] for v in lv) / min(v['rho_l'] for v in lv):.2g}x (the field "
                 "laws also start from these levels).")
    un = report.get("unexplained")
    if un:
        L += ["", "## Unexplained mismatch", "",
              f"The best model ({un['model']}) leaves a {un['measure']} stroke RMSE of {un['rmse'] * 1e6:.3g} um, "
              f"{un['ratio']:.1f}x the sensor noise: the catalog does not explain these data. Where it still "
              f"misses:", ""]
        if un["windows"]:
            L += ["| recording | window | t (s) | RMS (um) | mean (um) | signature |", "|---|---|---|---|---|---|"]
            L += [f"| {w['recording']} | {w['window']} | {w['t_start']:.2f}-{w['t_end']:.2f} | "
                  f"{w['rms_error'] * 1e6:.3g} | {w['mean_error'] * 1e6:+.3g} | {w['signature']} |"
                  for w in un["windows"]]
        else:
            L.append("No single window stands out: the error is spread over the recordings.")
        L += ["", "How far each tried entry got:", "",
              "| candidate | fitted | training RMSE (um) | held-out RMSE (um) | delta BIC | note |",
              "|---|---|---|---|---|---|"]
        for k, t in un["tried"].items():
            if t["fitted"]:
                L.append(f"| {k} | round {t['round']} | {um(t['train_rmse'])} | {um(t['heldout_rmse'])} | "
                         f"{t['delta_bic']:+.1f} | {t.get('stopped', '')} |")
            else:
                r = t["predicted_heldout_ratio"]
                pred = "" if r is None else f"first step predicted held-out x{r:.2f}; "
                L.append(f"| {k} | no | - | - | - | {pred}{t['why']} |")
        for r in un.get("training_only") or []:
            L += ["", f"{r['candidate']} reaches the noise on the trained conditions ({um(r['train_rmse'])} um, "
                  f"{r['train_rmse'] / un['sensor_noise']:.2f} noises) but predicts the held-out ones worse "
                  f"({um(r['heldout_rmse'])} um): the trained conditions do not determine it where the held-out ones "
                  "lie. A condition recorded there (or, under a polarity inversion, a DC hold) would tell."]
    L += ["", "## Candidates", ""]
    L += ["Each candidate is first screened (a score test: the BIC change a first fitting step predicts); the "
          "shortlisted ones are fitted in full.", ""]
    lo, hi = taken_rounds(D)
    for i, rnd in enumerate(D.rounds):
        against = "the baseline" if i == lo else " + ".join(e.name for e in (D.chain or D.kept)[:i - lo])
        if not lo <= i < hi:
            against = ("a selection at a coarser N, not taken" if i < lo else
                       "a selection run again at a finer N, not taken")
        L += [f"Round {i + 1} (against {against}):", "",
              "| candidate | screen: predicted delta BIC | delta BIC | held-out RMSE (um) | held-out reduction | "
              "parameters |", "|---|---|---|---|---|---|"]
        for name, ev in rnd.items():
            pred = f"{ev['screen']['predicted_delta_bic']:+.1f}" if "screen" in ev else "-"
            if "error" in ev:
                L.append(f"| {name} | {pred} | - | - | - | {ev['error']} |")
                continue
            raced = ev.get("raced")
            if raced and "delta_bic" in raced:
                name = f"{name} (raced: {raced['delta_bic']:+.1f} after {raced['evaluations']} evaluations)"
            if not ev.get("fitted"):
                why = "skipped: an accepted candidate beats it" if ev.get("skipped") else "not fitted"
                L.append(f"| {name} | {pred} | {why} | - | - | - |")
                continue
            pars = ", ".join(f"{k} = {p['value']:.4g} +- {p['stderr']:.2g}" for k, p in ev["parameters"].items())
            if ev.get("stopped"):
                pars = f"{pars} ({ev['stopped']})"
            if ev.get("late"):
                name = f"{name} (fitted late: the shortlist's fits left the mismatch at {STRONG_ERROR:g}+ noises)"
            red = ev["heldout_reduction"]
            L.append(f"| {name} | {pred} | {ev['delta_bic']:+.1f} | {um(ev['heldout_rmse'])} | "
                     f"{'-' if red is None else f'{red * 100:+.1f} %'} | {pars} |")
        L.append("")
    notes = [(r.name, n) for r in D.dataset.recordings for n in r.notes]
    if notes:
        L += ["## Data handling", ""] + [f"- {a}: {b}" for a, b in notes] + [""]
    L += ["## Plots", ""] + [f"![{k}]({v})" for k, v in plots.items()]
    return "\n".join(L) + "\n"


def _runs_text(z: float) -> str:
    """A window's runs test for report.md: its z score, or what -inf means (locate.runs_z:
    every residual of the window on one side)."""
    return "all one sign" if z == -math.inf else f"{z:.1f}"


def write(D, out) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    # report.json is written last: present, the whole report is (an interrupted write, or
    # one that failed, leaves none, and no earlier run's beside this one's files)
    (out / "report.json").unlink(missing_ok=True)
    report = to_json(D)
    # the improved model as a parameter file, and each recording's drive as a protocol file
    report["improved_params"] = write_improved(D, out)
    report["protocols"] = write_protocols(D, out)
    plots = {}
    plot_residuals(D, out / "residuals.png")
    plots["residuals"] = "residuals.png"
    plot_overlays(D, out / "overlays.png")
    plots["overlays"] = "overlays.png"
    if plot_terms(D, out / "fitted_terms.png"):
        plots["fitted terms"] = "fitted_terms.png"
    write_text_atomic(out / "report.md", to_markdown(D, report, plots))
    write_text_atomic(out / "report.json", json.dumps(report, indent=1))
    return report


def _first_check(r: dict) -> str:
    """The resolution check's first finer N, when the kept entries' cut shrank there and it
    was made again at twice those elements (rules._shrinks), as a phrase."""
    fc = r.get("first_check")
    if not fc:
        return ""
    cut = f"; at N = {fc['N']} the squared error it removed was {fc['cut_ratio']:.0%} of that at N = {r['N']}"
    if fc.get("deeper", {}).get("inconclusive"):
        return f"{cut}, but at N = {fc['deeper']['N']} the models fit no better: the check at N = {fc['N']} stands"
    return f"{cut}, so it was checked again at N = {r['N_fine']}"
