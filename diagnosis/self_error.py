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
twice the elements. The verdict is not changed here.
"""
from __future__ import annotations

from .fit import model_strokes, stroke_rms
from .rules import _um, fine_N

SELF_REF = 4     # the reference: two doublings finer (the continuum scheme's error falls ~4x per doubling)
SELF_TOL = 1.0   # the model's own error, in sensor noises, from which the report says so


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
