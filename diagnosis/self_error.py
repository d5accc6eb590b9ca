"""The final model's own discretization error at its fitted values (diagnose.py, on the final model).

Every resolution step compares fits: a model refitted at twice the elements against the
data. A fit compensates its own discretization error by moving its values, and a coarse
fit can fit as well as a finer one, or better, while both are far from the continuum. A
strong polarization branch under 1 Hz polarity inversion (lab_fine rig, trial seed
326037469, #8: chi_p 0.238, tau_p 0.556 s) was named at N = 21 with chi_p 0.063 and an
Eq. (21) law beside it; the kept model refitted at 41 fitted worse (2.48 -> 2.58 um), so
the values stood. The model itself at those values is 10.1 um off its N = 651 solution
at N = 21 (4.7 at 81, 1.7 at 161), against 1.7 um noise; the branch alone fitted at N =
161 gives chi_p 0.195, tau_p 0.50 s, 1.16 noises held out.

No data enter here: the final model is run at its N and at SELF_REF times its elements
(its training recordings, each with its own resistivity factor and timing; one batch each)
and the RMS difference of the strokes is its own error. At SELF_TOL sensor noises or more
the report says so - the named values carry the grid's bias - and how far it falls at
twice the elements.

At SELF_AGAIN noises or more the resolution check runs again (diagnose._again), once, at
the finer N where the error, falling at its measured rate per doubling, is within SELF_TOL
noises (again_N; at most SELF_N_MAX times the dataset's nominal N): the baseline and the
kept model refitted there, and each physics entry of two or more on top of the rest - the
check a doubling finer was misled by an error not monotone in N. Not where the final
model reaches the noise (SELF_FIT, held out and in training): data the model made on its
own grid fit it there and a finer model fits them worse (examples/workflow.py --quick,
made at N = 21: 13 noises off itself, 0.97 noises in training, its refit at 41 6x worse) -
these data cannot ask for a finer N, and the report says the values carry the grid's
bias.
"""
from __future__ import annotations

from .fit import model_strokes, stroke_rms
from .rules import _um, _worst_error, fine_N

SELF_REF = 4     # the reference: two doublings finer (the continuum scheme's error falls ~4x per doubling)
SELF_TOL = 1.0   # the model's own error, in sensor noises, from which the report says so
SELF_AGAIN = 2.0  # ... and from which the resolution check runs again at a finer N (again_N)
SELF_N_MAX = 8    # ... at most this many times the dataset's nominal N (as the value check)
SELF_FIT = 1.1    # ... unless its worse error (held out, training) is within this many noises: the data are
#                   reached at this N (rules.SHAPE_DONE's "at the noise")


def again_N(rec, nominal_N: int, final) -> int | None:
    """The N the resolution check runs again at (module docstring): the first doubling where the
    error, falling at its measured rate, is within SELF_TOL noises, else the finest within
    SELF_N_MAX times the nominal N; None when the final model's own error (self_check's
    record) is below SELF_AGAIN noises, was not measured at twice its elements, does not
    fall, when the final model `final` reaches the noise (SELF_FIT), or no finer N is
    allowed."""
    sigma = final.sigma
    if not rec or rec["rmse"] < SELF_AGAIN * sigma or rec.get("rmse_fine") is None:
        return None
    if _worst_error(final) <= SELF_FIT * sigma:
        return None
    q = rec["rmse_fine"] / rec["rmse"]
    if not q < 1.0:
        return None
    n_max = SELF_N_MAX * (nominal_N - 1) + 1
    N, e = fine_N(rec["N"]), rec["rmse_fine"]
    while e > SELF_TOL * sigma and fine_N(N) <= n_max:
        N, e = fine_N(N), e * q
    return N if N <= n_max else None


def self_check(dataset, final, executor, say) -> dict | None:
    """{N, N_ref, rmse, ratio (rmse / sensor noise), N_fine, rmse_fine (at twice the
    elements, against the same reference; only when the ratio is SELF_TOL or more),
    flagged} of the final model, or None when it cannot be measured."""
    N = final.params.N
    N_ref = SELF_REF * (N - 1) + 1
    try:
        strokes = model_strokes(dataset, final, [N, N_ref], executor)
    except Exception:            # a second account only
        return None
    if strokes is None:
        return None
    here, ref = strokes
    e = stroke_rms(here, ref)
    out = {"N": N, "N_ref": N_ref, "rmse": e, "ratio": e / final.sigma, "flagged": e >= SELF_TOL * final.sigma}
    if out["flagged"]:
        try:             # against the same reference runs
            fine = model_strokes(dataset, final, [fine_N(N)], executor)
        except Exception:
            fine = None
        ef = None if fine is None else stroke_rms(fine[0], ref)
        out.update(N_fine=fine_N(N), rmse_fine=ef)
        say(f"the final model's own discretization error at its values: {_um(e)} at N = {N} against N = {N_ref} "
            f"({out['ratio']:.1f}x the noise)" + (f", {_um(ef)} at N = {fine_N(N)}" if ef is not None else ""))
    return out
