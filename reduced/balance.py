"""Balanced truncation and real modal form of a stable continuous-time LTI system.

Pure linear algebra on (A, B, C, D) with x' = A x + B u, y = C x + D u; no units.

Balanced truncation is the square-root method (Laub et al. 1987, Tombs & Sorensen 1987):
the Gramians are factored, P = S S^T and Q = R R^T, and the SVD R^T S = U diag(sigma) V^T
gives the Hankel singular values sigma and the projections T = S V_r sigma_r^(-1/2),
Ti = sigma_r^(-1/2) U_r^T R^T (Ti T = I_r). The reduced model (Ti A T, Ti B, C T, D) is
stable and its error obeys ||G - G_r||_inf <= 2 * (sum of the discarded sigma).

The Gramians come from scipy's Bartels-Stewart solver, not Hammarling's factored solver,
so Hankel singular values far below the largest carry an absolute error of roughly
sqrt(eps) * sigma_1: they are reliable for choosing an order, not as tiny numbers.
SLICOT (through python-control's balred) is used when slycot is installed and asked for.
"""
from __future__ import annotations

import importlib.util
from dataclasses import dataclass

import numpy as np
from scipy import linalg

METHODS = ("auto", "scipy", "slycot")
SLYCOT_HINT = "pip install dfa-toolkit[slycot]"


def _matrix(name, value):
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        raise ValueError(f"{name}: expected a real numeric array, got dtype {arr.dtype}")
    arr = arr.astype(float)
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name}: contains non-finite entries (NaN or inf)")
    return arr


def _validate(A, B, C, D=None, *, hurwitz=True):
    """The system as 2-D float arrays with consistent shapes; ValueError names the culprit."""
    A = _matrix("A", A)
    if A.ndim != 2 or A.shape[0] != A.shape[1] or A.shape[0] == 0:
        raise ValueError(f"A: expected a non-empty square matrix, got shape {A.shape}")
    n = A.shape[0]
    B = _matrix("B", B)
    if B.ndim == 1:                      # a single input given as an n-vector
        B = B[:, None]
    if B.ndim != 2 or B.shape[0] != n or B.shape[1] == 0:
        raise ValueError(f"B: expected shape ({n}, m) or ({n},) to match A {A.shape}, got {B.shape}")
    C = _matrix("C", C)
    if C.ndim == 1:                      # a single output given as an n-vector
        C = C[None, :]
    if C.ndim != 2 or C.shape[1] != n or C.shape[0] == 0:
        raise ValueError(f"C: expected shape (p, {n}) or ({n},) to match A {A.shape}, got {C.shape}")
    p, m = C.shape[0], B.shape[1]
    if D is None:
        D = np.zeros((p, m))
    else:
        D = _matrix("D", D)
        if D.ndim == 0 or D.size == 1 and p * m == 1:
            D = D.reshape(1, 1) if p * m == 1 else np.full((p, m), float(D))
        if D.shape != (p, m):
            raise ValueError(f"D: expected shape ({p}, {m}) (outputs of C, inputs of B), got {D.shape}")
    if hurwitz:
        # The Gramians (infinite-horizon integrals) exist only for a stable A.
        worst = np.linalg.eigvals(A).real.max()
        if not worst < 0.0:
            raise ValueError(f"A: must be Hurwitz (every eigenvalue with a negative real part); "
                             f"the largest real part is {worst:.6g}")
    return A, B, C, D


def _psd_factor(G):
    """F with F F^T = G for a symmetric positive semidefinite G known only up to round-off.

    eigh rather than cholesky: a computed Gramian is often indefinite at the round-off level
    (tiny negative eigenvalues for nearly uncontrollable directions), where cholesky fails;
    clipping those eigenvalues to zero changes G by no more than the round-off it already has.
    """
    w, V = linalg.eigh(0.5 * (G + G.T))   # symmetrize: the Lyapunov solver's output is not exactly
    return V * np.sqrt(np.clip(w, 0.0, None))


def _square_root_svd(A, B, C):
    """Gramian factors S, R and the SVD R^T S = U diag(hsv) Vt."""
    # solve_continuous_lyapunov(a, q) solves a X + X a^H = q.
    P = linalg.solve_continuous_lyapunov(A, -B @ B.T)
    Q = linalg.solve_continuous_lyapunov(A.T, -C.T @ C)
    S, R = _psd_factor(P), _psd_factor(Q)
    U, hsv, Vt = linalg.svd(R.T @ S)
    return S, R, U, hsv, Vt


def hankel_singular_values(A, B, C) -> np.ndarray:
    """Hankel singular values of a stable continuous-time system, in descending order.

    A is n x n and Hurwitz, B is n x m (or an n-vector), C is p x n (or an n-vector).
    They are sqrt(eig(P Q)) for the controllability and observability Gramians P and Q.
    """
    A, B, C, _ = _validate(A, B, C)
    return _square_root_svd(A, B, C)[3]


@dataclass(frozen=True)
class BalancedModel:
    """A balanced truncation: the reduced (A, B, C, D) and what it was made from.

    hsv holds every Hankel singular value of the full system (descending); T (n x r) and
    Ti (r x n) are the projections x ~ T x_r, x_r = Ti x (None when SLICOT did the work).
    """
    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    hsv: np.ndarray
    T: np.ndarray | None
    Ti: np.ndarray | None
    method: str

    @property
    def order(self) -> int:
        return self.A.shape[0]

    @property
    def error_bound(self) -> float:
        """The H-infinity error bound 2 * (sum of the discarded Hankel singular values)."""
        return 2.0 * float(np.sum(self.hsv[self.order:]))

    def to_statespace(self):
        """The reduced model as a control.StateSpace (python-control is an optional extra)."""
        try:
            import control
        except ImportError as exc:
            raise ImportError("to_statespace needs python-control (pip install control)") from exc
        return control.StateSpace(self.A, self.B, self.C, self.D)


def _slycot_available() -> bool:
    return (importlib.util.find_spec("slycot") is not None
            and importlib.util.find_spec("control") is not None)


def _choose_order(hsv, order, tol):
    n = hsv.size
    if (order is None) == (tol is None):
        raise ValueError("order, tol: give exactly one of them (order = states kept; "
                         "tol = drop states whose sigma_k / sigma_1 < tol)")
    if hsv[0] <= 0.0:
        raise ValueError("B, C: every Hankel singular value is zero (no input reaches the output)")
    if order is not None:
        if isinstance(order, bool) or not isinstance(order, (int, np.integer)):
            raise ValueError(f"order: expected an integer, got {order!r}")
        if not 1 <= order <= n:
            raise ValueError(f"order: must be between 1 and the full order {n}, got {order}")
        order = int(order)
    else:
        tol = float(tol)
        if not 0.0 < tol <= 1.0:
            raise ValueError(f"tol: must be in (0, 1] (a ratio sigma_k / sigma_1), got {tol!r}")
        order = int(np.count_nonzero(hsv >= tol * hsv[0]))
    # sigma_r^(-1/2) scales the projections: a kept value at round-off level would
    # blow them up, and it marks a non-minimal realization rather than a state worth keeping.
    if hsv[order - 1] <= n * np.finfo(float).eps * hsv[0]:
        kept = int(np.count_nonzero(hsv > n * np.finfo(float).eps * hsv[0]))
        raise ValueError(f"order: {order} keeps Hankel singular values that are zero to round-off "
                         f"(the realization is not minimal); use order <= {kept}")
    return order


def balanced_truncation(A, B, C, D=None, order=None, tol=None, method="auto") -> BalancedModel:
    """Square-root balanced truncation of a stable continuous-time system.

    order: number of states kept; or tol: drop the states whose sigma_k / sigma_1 < tol
    (exactly one of the two). method: "scipy" (always available), "slycot" (SLICOT AB09AD
    via control.balred; needs the optional slycot) or "auto" (slycot when installed).
    The reduced model is stable and ||G - G_r||_inf <= BalancedModel.error_bound.
    """
    if method not in METHODS:
        raise ValueError(f"method: expected one of {METHODS}, got {method!r}")
    A, B, C, D = _validate(A, B, C, D)
    if method == "slycot" and not _slycot_available():
        raise ImportError(f"method='slycot' needs the optional packages slycot and python-control: "
                          f"{SLYCOT_HINT} (or use method='scipy')")
    if method == "auto":
        method = "slycot" if _slycot_available() else "scipy"

    # The HSVs are computed here on either path: they pick the order for tol and give the bound.
    S, R, U, hsv, Vt = _square_root_svd(A, B, C)
    r = _choose_order(hsv, order, tol)

    if method == "slycot":
        import control
        red = control.balred(control.StateSpace(A, B, C, D), r, method="truncate")
        # AB09AD may return fewer states than asked when the tail is at round-off level;
        # error_bound follows the order actually returned.
        return BalancedModel(np.asarray(red.A), np.asarray(red.B), np.asarray(red.C), np.asarray(red.D),
                             hsv, None, None, "slycot")

    scale = 1.0 / np.sqrt(hsv[:r])
    T = (S @ Vt[:r].T) * scale              # S V_r sigma_r^(-1/2)
    Ti = scale[:, None] * (U[:, :r].T @ R.T)  # sigma_r^(-1/2) U_r^T R^T
    return BalancedModel(Ti @ A @ T, Ti @ B, C @ T, D.copy(), hsv, T, Ti, "scipy")


def modal_form(A, B, C):
    """(A_diag, B_m, C_m) in real modal coordinates, for A with real distinct eigenvalues.

    x = V z with V the eigenvectors, each column scaled so that the mode's row of B_m has
    1 as its largest-magnitude entry (for one input: B_m entries are 1); a mode with a
    row of B_m at round-off level (uncontrollable) keeps unit-norm V and that row is set
    to zero. Modes are sorted slowest first (increasing |eigenvalue|). The transfer
    function C (sI - A)^-1 B is unchanged. ValueError if the eigenvalues are complex or
    repeated (no real diagonal form, or an ill-conditioned one).
    """
    A, B, C, _ = _validate(A, B, C, hurwitz=False)
    n = A.shape[0]
    lam, V = np.linalg.eig(A)
    # LAPACK returns exactly zero imaginary parts for real eigenvalues (1x1 Schur blocks),
    # and numpy then hands back real arrays: any complex result is a genuine complex pair.
    if np.iscomplexobj(lam) and np.any(lam.imag != 0.0):
        raise ValueError("A: has complex eigenvalues; the real modal (diagonal) form needs real ones")
    lam, V = lam.real, V.real
    idx = np.argsort(np.abs(lam), kind="stable")
    lam, V = lam[idx], V[:, idx]
    scale = max(1.0, np.abs(lam).max())
    if n > 1 and np.min(np.diff(np.sort(lam))) <= 1e-8 * scale:
        raise ValueError("A: has repeated (or nearly repeated) eigenvalues; modal_form needs distinct ones")
    Bm = np.linalg.solve(V, B)
    Cm = C @ V
    tiny = n * np.finfo(float).eps * max(np.abs(Bm).max(), np.finfo(float).tiny)
    for i in range(n):
        b = Bm[i, np.argmax(np.abs(Bm[i]))]
        if abs(b) <= tiny:
            Bm[i] = 0.0        # uncontrollable mode: no scale makes its row 1
            continue
        # z_i -> z_i / b: the row of B_m is divided by b, the column of C_m multiplied by it.
        Bm[i] /= b
        Cm[:, i] *= b
    return np.diag(lam), Bm, Cm
