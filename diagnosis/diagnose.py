"""The diagnosis: baseline fit, location of the mismatch, and forward selection over the
catalog and the nominal values.

1. Baseline: the paper's model with the nominal actuator, rho_l fitted (fit.py).
2. Locate: systematic windows of the baseline's residuals (locate.py).
3. Forward selection: every catalog entry and every nominal correction is fitted on top
   of the current model (all its free parameters re-fitted jointly). The best by BIC is
   kept when it lowers BIC by more than BIC_MIN *and* the held-out RMSE by more than
   HELDOUT_MIN (data it was not fitted to); then the next round, on top of it, with the
   candidates that lowered BIC in the first round, until nothing passes or MAX_ROUNDS. A kept catalog entry is missing physics; a kept
   nominal correction a parameter error (reported under corrected_parameters).
4. "No missing physics found" when no catalog entry is kept.

Evidence kept for every candidate of every round: its BIC and AIC differences against the
model it extends, train and held-out RMSE, fitted parameters with standard errors.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from .catalog import NOMINAL, PHYSICS, baseline_spec
from .fit import fit, local_executor
from .locate import condition_trends, locate

BIC_MIN = 10.0       # "very strong" evidence on the BIC scale
HELDOUT_MIN = 0.10   # relative held-out RMSE reduction a kept candidate must bring
MAX_ROUNDS = 3


@dataclass
class Diagnosis:
    dataset: object
    baseline: object                 # FitResult
    final: object                    # FitResult (the baseline when nothing was kept)
    kept: list                       # catalog / nominal entries kept, in order
    rounds: list                     # per round: {name: evidence}
    windows: list                    # locate.Window of the baseline
    trends: list                     # condition-level sentences
    wall_time: float
    fits: dict = field(default_factory=dict)   # name of the kept chain -> FitResult

    @property
    def missing_physics(self) -> list:
        return [e for e in self.kept if e.kind == "physics"]

    @property
    def corrections(self) -> list:
        return [e for e in self.kept if e.kind == "nominal"]

    @property
    def mismatch(self) -> bool:
        return any(w.systematic for w in self.windows)


def _evidence(f, ref) -> dict:
    return {"delta_bic": f.bic - ref.bic, "delta_aic": f.aic - ref.aic, "train_rmse": f.train_rmse,
            "wall_time": f.wall_time, "model_runs": f.runs,
            "heldout_rmse": f.heldout_rmse, "heldout_reduction": (1 - f.heldout_rmse / ref.heldout_rmse)
            if f.heldout_rmse is not None and ref.heldout_rmse else None, "parameters": f.parameters_dict()}


def _promising(ev) -> bool:
    """Whether a candidate's first-round evidence earns it a place in later rounds: it
    lowered BIC at all (an effect that explains nothing alone rarely starts to once
    another is modelled; it saves most of the later rounds' fits)."""
    return ev is not None and "error" not in ev and ev["delta_bic"] < 0


def _accept(f, ref) -> bool:
    if f.bic > ref.bic - BIC_MIN:
        return False
    if f.heldout_rmse is None or ref.heldout_rmse is None:
        return True
    return f.heldout_rmse < (1 - HELDOUT_MIN) * ref.heldout_rmse


def diagnose(dataset, executor=None, progress=None, holdout=None, candidates=None) -> Diagnosis:
    """Run the diagnosis (module docstring). executor: where the full-model runs go
    (default: local processes); progress: callable(str) for status lines."""
    wall = time.perf_counter()
    say = progress or (lambda s: None)
    own = executor is None
    if own:
        executor = local_executor()
    try:
        base = dataset.params
        say("baseline fit (rho_l)")
        f0 = fit(dataset, baseline_spec(base), base=base, holdout=holdout, executor=executor)
        say(f"baseline: train RMSE {f0.train_rmse * 1e6:.3g} um, held out {_um(f0.heldout_rmse)}; locating")
        windows = locate(dataset, f0)
        trends = condition_trends(dataset, windows)
        pool = list(candidates) if candidates is not None else PHYSICS + NOMINAL
        V_max = max(abs(r.hold_voltage) for r in dataset.recordings)
        kept, rounds, current = [], [], f0
        for rnd in range(MAX_ROUNDS):
            ev, fits = {}, {}
            for e in pool:
                if any(k.name == e.name for k in kept):     # one form of an entry at most
                    continue
                if rounds and not _promising(rounds[0].get(e.key)):
                    # it did not lower BIC at all on its own: it is not refitted on top
                    continue
                p = e.prepare(current.params, V_max)
                spec = baseline_spec(p) + [fp for k in kept for fp in k.spec(p)] + e.spec(p)
                say(f"round {rnd + 1}: {e.key}")
                best, errors = None, []
                for st in (e.starts(p) if e.starts else [{}]):
                    try:
                        f = fit(dataset, spec, base=p.replace(**st) if st else p, holdout=holdout,
                                executor=executor, warm=current)
                    except Exception as exc:   # a candidate the model cannot run: evidence says why
                        errors.append(f"{type(exc).__name__}: {exc}")
                        continue
                    if best is None or f.cost < best.cost:
                        best = f
                if best is None:
                    ev[e.key] = {"error": "; ".join(errors)}
                    continue
                fits[e.key] = best
                ev[e.key] = _evidence(best, current)
            rounds.append(ev)
            ok = [n for n, f in fits.items() if _accept(f, current)]
            if not ok:
                break
            best_key = min(ok, key=lambda n: fits[n].bic)
            kept.append(next(e for e in pool if e.key == best_key))
            current = fits[best_key]
            say(f"kept {best_key}: BIC {ev[best_key]['delta_bic']:+.1f}, held out {_um(current.heldout_rmse)}")
        return Diagnosis(dataset, f0, current, kept, rounds, windows, trends, time.perf_counter() - wall)
    finally:
        if own:
            executor.shutdown()


def _um(x):
    return "-" if x is None else f"{x * 1e6:.3g} um"
