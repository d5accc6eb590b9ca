"""The diagnosis written out: report.json (*contract*), report.md and its plots."""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dfa_model.fileio import write_text_atomic


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
    final = D.final if D.kept else None
    missing = []
    for i, e in enumerate(D.kept):
        if e.kind != "physics":
            continue
        keys = [fp.key for fp in e.spec(D.final.params)]
        missing.append({"name": e.name, "description": e.description,
                        "parameters": {k: {"value": D.final.values[k], "stderr": D.final.stderr[k]} for k in keys},
                        "evidence": D.rounds[i][e.name]})
    corrected = {}
    nominal = D.dataset.params
    for k, v in D.final.values.items():
        if k in ("rho_l", "q_rho") or any(e.kind == "nominal" and e.name == f"nominal:{k}" for e in D.kept):
            nom = getattr(nominal, "rho_l" if k == "q_rho" else k)
            # corrected: the data move it beyond two standard errors of the fit
            corrected[k] = {"nominal": nom, "fitted": v, "stderr": D.final.stderr[k],
                            "corrected": bool(abs(v - nom) > 2 * D.final.stderr[k])}
    out = {
        "mismatch": bool(D.mismatch),
        "missing_physics": missing,
        "corrected_parameters": corrected,
        "located": [w.to_dict() for w in D.windows if w.systematic],
        "fit": {"baseline": _fit_dict(D.baseline), "improved": _fit_dict(final)},
        "conclusion": conclusion(D),
        "headline": headline(D),
        "trends": D.trends,
        "candidates": D.rounds,
        "recordings": [{"recording": r.name, "voltage": r.hold_voltage, "force": r.force_mean,
                        "notes": r.notes, "rho_factor_baseline": D.baseline.rho_factors.get(r.name),
                        "offset_baseline": D.baseline.offsets.get(r.name)} for r in D.dataset.recordings],
        "wall_time": D.wall_time,
    }
    return _clean(out)


def hold_speed(t, x, t0, t1, span=0.5) -> float:
    """Average unzipping speed over the hold [t0, t1] (m/s, positive when unzipping): the
    drop between the mean strokes of its first and last `span` s over the time between
    their centres (the Sec. 3.1 peak-to-end drop, robust to sensor noise)."""
    a = (t >= t0) & (t < t0 + span)
    b = (t > t1 - span) & (t <= t1)
    return float((np.mean(x[a]) - np.mean(x[b])) / (t1 - t0 - span))


def headline(D) -> list:
    """Per condition, the paper's headline metric (hold_speed): measured mean and the
    repetitions' SD, and the baseline's and the improved model's error. A mismatch is
    concealed when the baseline's error lies within the repetition spread."""
    out = []
    for c, recs in D.dataset.conditions().items():
        t0, t1 = recs[0].reset_end, recs[0].duration
        meas = [hold_speed(r.t, r.stroke, t0, t1) for r in recs]
        base = [hold_speed(r.t, D.baseline.simulated[r.name], t0, t1) for r in recs]
        row = {"voltage": c[0], "force": c[1], "repetitions": len(recs), "speed_measured": float(np.mean(meas)),
               "speed_spread": float(np.std(meas, ddof=1)) if len(recs) > 1 else None,
               "speed_error_baseline": float(np.mean(base) - np.mean(meas))}
        if D.kept:
            imp = [hold_speed(r.t, D.final.simulated[r.name], t0, t1) for r in recs]
            row["speed_error_improved"] = float(np.mean(imp) - np.mean(meas))
        row["concealed"] = None if row["speed_spread"] is None else \
            bool(abs(row["speed_error_baseline"]) <= row["speed_spread"])
        out.append(row)
    return out


def conclusion(D) -> str:
    phys = [e.name for e in D.missing_physics]
    corr = [e.name.split(":", 1)[1] for e in D.corrections]
    parts = []
    if phys:
        parts.append("missing physics: " + ", ".join(phys))
    else:
        parts.append("no missing physics found")
    if corr:
        parts.append("nominal value(s) corrected: " + ", ".join(corr))
    return "; ".join(parts)


def _per_condition(D, row_height):
    """(pyplot, {condition: recordings}, figure, axes): one row per condition."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    conds = D.dataset.conditions()
    fig, axes = plt.subplots(len(conds), 1, figsize=(9, row_height * len(conds) + 0.8), sharex=True, squeeze=False)
    return plt, conds, fig, axes


def _finish(plt, fig, axes, path):
    axes[0, 0].legend(fontsize=8, loc="upper right")
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_residuals(D, path):
    plt, conds, fig, axes = _per_condition(D, 1.9)
    for ax, (c, recs) in zip(axes[:, 0], conds.items()):
        for r in recs:
            ax.plot(r.t, D.baseline.residual(r) * 1e6, lw=0.5, color="C3", alpha=0.7)
            if D.kept:
                ax.plot(r.t, D.final.residual(r) * 1e6, lw=0.5, color="C2", alpha=0.7)
        held = " (held out)" if recs[0].name in D.baseline.heldout else ""
        ax.set_title(f"{c[0] / 1e3:g} kV, {c[1]:g} N{held}", fontsize=9, loc="left")
        ax.axhline(0, color="k", lw=0.5)
        ax.set_ylabel("um")
    axes[0, 0].plot([], [], color="C3", label="baseline")
    if D.kept:
        axes[0, 0].plot([], [], color="C2", label="improved")
    fig.suptitle("measured - model stroke, every recording", fontsize=10)
    _finish(plt, fig, axes, path)


def plot_overlays(D, path):
    plt, conds, fig, axes = _per_condition(D, 2.0)
    for ax, (c, recs) in zip(axes[:, 0], conds.items()):
        r = recs[0]
        ax.plot(r.t, (r.stroke - D.baseline.offsets[r.name]) * 1e3, lw=0.6, color="0.5", label="measured")
        ax.plot(r.t, (D.baseline.simulated[r.name] - D.baseline.offsets[r.name]) * 1e3, lw=1, color="C3",
                label="baseline")
        if D.kept:
            ax.plot(r.t, (D.final.simulated[r.name] - D.baseline.offsets[r.name]) * 1e3, lw=1, ls="--", color="C2",
                    label="improved")
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

    from dfa_model.kinematics import make
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
            E = np.linspace(0, 1.2e8, 100)
            q, m = f.values["q_rho"], f.values["m_rho"]
            sq, sm = f.stderr["q_rho"], f.stderr["m_rho"]
            rho = np.maximum(q + m * E, f.params.rho_min)
            band = np.sqrt(sq ** 2 + (sm * E) ** 2)
            ax.plot(E / 1e6, rho, color="C2")
            ax.fill_between(E / 1e6, rho - band, rho + band, color="C2", alpha=0.25)
            ax.set_xlabel("|E_l| (MV/m)")
            ax.set_ylabel("rho_l (ohm m)")
            ax.set_title("field-dependent resistivity (Eq. 21)", fontsize=9)
        else:
            keys = [fp.key for fp in e.spec(f.params)]
            ax.errorbar(range(len(keys)), [f.values[k] for k in keys], yerr=[f.stderr[k] for k in keys], fmt="o")
            ax.set_xticks(range(len(keys)), keys)
            ax.set_title(e.name, fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def to_markdown(D, report: dict, plots: dict) -> str:
    um = lambda x: "-" if x is None else f"{x * 1e6:.3g}"   # noqa: E731
    L = [f"# Diagnosis of {D.dataset.folder.name}", "",
         f"**{report['conclusion']}.** {len(D.dataset.recordings)} recordings, "
         f"{len(D.dataset.conditions())} conditions; held out: "
         f"{', '.join(sorted(set(D.baseline.heldout))) or 'none (a single condition)'}. Sensor noise from the data: "
         f"{D.baseline.sigma * 1e6:.3g} um RMS. Wall time {D.wall_time:.0f} s.", "",
         "## Before and after", "", "| model | train RMSE (um) | held-out RMSE (um) | BIC |", "|---|---|---|---|",
         f"| baseline (paper's model, rho_l fitted) | {um(D.baseline.train_rmse)} | {um(D.baseline.heldout_rmse)} | "
         f"{D.baseline.bic:.1f} |"]
    if D.kept:
        L.append(f"| + {' + '.join(e.name for e in D.kept)} | {um(D.final.train_rmse)} | {um(D.final.heldout_rmse)} | "
                 f"{D.final.bic:.1f} |")
    L += ["", "Headline metric (average unzipping speed over the hold, um/s; concealed: the baseline's error "
          "within the repetitions' SD):", "",
          "| condition | measured | repetition SD | baseline error | improved error | concealed |", "|---|---|---|---|---|---|"]
    for h in report["headline"]:
        f = lambda v: "-" if v is None else f"{v * 1e6:+.3g}"   # noqa: E731
        sd = "-" if h["speed_spread"] is None else f"{h['speed_spread'] * 1e6:.3g}"
        hidden = "-" if h["concealed"] is None else ("yes" if h["concealed"] else "no")
        L.append(f"| {h['voltage'] / 1e3:g} kV, {h['force']:g} N | {h['speed_measured'] * 1e6:.3g} | {sd} | "
                 f"{f(h['speed_error_baseline'])} | {f(h.get('speed_error_improved'))} | {hidden} |")
    L += ["", "## Fitted parameters", "", "| parameter | nominal | fitted | standard error |", "|---|---|---|---|"]
    for k, v in D.final.values.items():
        L.append(f"| {k} | {getattr(D.dataset.params, k, '-')} | {v:.4g} | {D.final.stderr[k]:.2g} |")
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
                     f"{w.excess:.1f} | {w.runs:.1f} | {w.effect:.1f} | {w.signature} |")
    for s in D.trends:
        L.append(f"- {s}")
    L += ["", "## Candidates", ""]
    for i, rnd in enumerate(D.rounds):
        L += [f"Round {i + 1} (against {'the baseline' if i == 0 else ' + '.join(e.name for e in D.kept[:i])}):", "",
              "| candidate | delta BIC | held-out RMSE (um) | held-out reduction | parameters |", "|---|---|---|---|---|"]
        for name, ev in rnd.items():
            if "error" in ev:
                L.append(f"| {name} | - | - | - | {ev['error']} |")
                continue
            pars = ", ".join(f"{k} = {p['value']:.4g} +- {p['stderr']:.2g}" for k, p in ev["parameters"].items())
            red = ev["heldout_reduction"]
            L.append(f"| {name} | {ev['delta_bic']:+.1f} | {um(ev['heldout_rmse'])} | "
                     f"{'-' if red is None else f'{red * 100:+.1f} %'} | {pars} |")
        L.append("")
    notes = [(r.name, n) for r in D.dataset.recordings for n in r.notes]
    if notes:
        L += ["## Data handling", ""] + [f"- {a}: {b}" for a, b in notes] + [""]
    L += ["## Plots", ""] + [f"![{k}]({v})" for k, v in plots.items()]
    return "\n".join(L) + "\n"


def write(D, out) -> dict:
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    report = to_json(D)
    write_text_atomic(out / "report.json", json.dumps(report, indent=1))
    plots = {}
    plot_residuals(D, out / "residuals.png")
    plots["residuals"] = "residuals.png"
    plot_overlays(D, out / "overlays.png")
    plots["overlays"] = "overlays.png"
    if plot_terms(D, out / "fitted_terms.png"):
        plots["fitted terms"] = "fitted_terms.png"
    write_text_atomic(out / "report.md", to_markdown(D, report, plots))
    return report
