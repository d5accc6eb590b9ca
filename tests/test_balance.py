"""Balanced truncation and modal form (reduced/balance.py) against independent computations."""
import importlib.util

import numpy as np
import pytest

from reduced.balance import balanced_truncation, hankel_singular_values, modal_form

W = np.logspace(-4, 4, 400)   # rad/s


def coupled_system(seed, n=12, uncontrollable=False):
    """Known real poles on the diagonal plus a small strictly upper-triangular coupling.

    The coupling keeps the poles exactly the diagonal (stable, real, distinct) while making
    the realization dense enough that balancing does real work. With uncontrollable=True
    the last state has no input and no coupling from the others: an exactly
    uncontrollable mode (its Hankel singular value is zero).
    """
    rng = np.random.default_rng(seed)
    poles = -np.logspace(-1, 2, n)
    A = np.diag(poles) + np.triu(0.1 * rng.standard_normal((n, n)) * np.sqrt(np.outer(poles, poles)), 1)
    B = rng.standard_normal(n)
    C = rng.standard_normal(n)
    if uncontrollable:
        A[-1, :-1] = 0.0
        B[-1] = 0.0
    return A, B, C


def freqresp(A, B, C, D=0.0, w=W):
    """G(jw) = C (jwI - A)^-1 B + D for a SISO system, one solve per frequency."""
    n = A.shape[0]
    B, C = np.reshape(B, (n, 1)), np.reshape(C, (1, n))
    eye = np.eye(n)
    return np.array([(C @ np.linalg.solve(1j * wk * eye - A, B))[0, 0] for wk in w]) + np.squeeze(D)


def gramian_kron(A, BBt):
    """P with A P + P A^T + BBt = 0 by the Kronecker form: independent of scipy's Lyapunov solver."""
    n = A.shape[0]
    eye = np.eye(n)
    vecP = np.linalg.solve(np.kron(eye, A) + np.kron(A, eye), -BBt.reshape(-1, order="F"))
    return vecP.reshape(n, n, order="F")


@pytest.mark.parametrize("r", [2, 4, 6])
def test_hinf_error_bound_and_stability(r):
    A, B, C = coupled_system(1)
    red = balanced_truncation(A, B, C, order=r, method="scipy")
    assert red.order == r and red.method == "scipy"
    err = np.abs(freqresp(A, B, C) - freqresp(red.A, red.B, red.C)).max()
    assert red.error_bound == pytest.approx(2 * red.hsv[r:].sum())
    assert err <= red.error_bound * (1 + 1e-6)
    assert np.linalg.eigvals(red.A).real.max() < 0


def test_reduced_model_is_balanced():
    # Both Gramians of the truncated model equal diag(sigma_1..sigma_r): the balancing itself.
    A, B, C = coupled_system(2)
    red = balanced_truncation(A, B, C, order=5)
    P = gramian_kron(red.A, red.B @ red.B.T)
    Q = gramian_kron(red.A.T, red.C.T @ red.C)
    S = np.diag(red.hsv[:5])
    assert np.allclose(P, S, atol=1e-8 * red.hsv[0])
    assert np.allclose(Q, S, atol=1e-8 * red.hsv[0])
    assert np.allclose(red.Ti @ red.T, np.eye(5), atol=1e-8)


def test_hsv_match_sqrt_eig_PQ():
    A, B, C = coupled_system(3)
    P = gramian_kron(A, np.outer(B, B))
    Q = gramian_kron(A.T, np.outer(C, C))
    ref = np.sort(np.sqrt(np.clip(np.linalg.eigvals(P @ Q).real, 0, None)))[::-1]
    hsv = hankel_singular_values(A, B, C)
    assert np.all(np.diff(hsv) <= 0)
    assert np.allclose(hsv[:4], ref[:4], rtol=1e-8)          # the large ones: relatively
    assert np.allclose(hsv, ref, rtol=0, atol=1e-7 * ref[0])  # the tail: to sqrt(eps) * sigma_1


def test_full_order_keeps_dc_gain_mimo():
    rng = np.random.default_rng(4)
    A, _, _ = coupled_system(4, n=9)
    B, C, D = rng.standard_normal((9, 3)), rng.standard_normal((2, 9)), rng.standard_normal((2, 3))
    red = balanced_truncation(A, B, C, D, order=9)
    dc = D - C @ np.linalg.solve(A, B)
    dc_r = red.D - red.C @ np.linalg.solve(red.A, red.B)
    assert np.abs(dc_r - dc).max() <= 1e-10 * np.abs(dc).max()
    assert red.error_bound == 0.0


def test_uncontrollable_mode_has_zero_hsv_and_truncates_exactly():
    A, B, C = coupled_system(5, n=8, uncontrollable=True)
    hsv = hankel_singular_values(A, B, C)
    assert hsv[-1] < 1e-10 * hsv[0]
    red = balanced_truncation(A, B, C, order=7)
    G = freqresp(A, B, C)
    assert np.abs(freqresp(red.A, red.B, red.C) - G).max() <= 1e-10 * np.abs(G).max()
    # keeping the zero value would divide by it: refused, with the order that works
    with pytest.raises(ValueError, match=r"^order: .*order <= 7"):
        balanced_truncation(A, B, C, order=8)


def test_tol_chooses_the_order():
    A, B, C = coupled_system(1)
    hsv = hankel_singular_values(A, B, C)
    tol = 1e-4
    red = balanced_truncation(A, B, C, tol=tol)
    assert red.order == np.count_nonzero(hsv / hsv[0] >= tol)
    assert np.all(red.hsv[red.order:] / red.hsv[0] < tol)


@pytest.mark.parametrize("kwargs, name", [
    (dict(A=np.diag([-1.0, 0.5, -2.0])), "A"),                       # unstable
    (dict(A=np.diag([-1.0, 0.0, -2.0])), "A"),                       # marginal
    (dict(A=np.ones((3, 2))), "A"),
    (dict(B=np.ones((4, 1))), "B"),
    (dict(C=np.ones((1, 2))), "C"),
    (dict(D=np.ones((2, 2))), "D"),
    (dict(B=np.array([1.0, np.nan, 0.0])), "B"),
    (dict(C=np.array([[1.0, np.inf, 0.0]])), "C"),
    (dict(A=np.diag([-1.0, -2.0, np.nan])), "A"),
    (dict(order=None), "order, tol"),                               # neither order nor tol
    (dict(order=4), "order"),
    (dict(order=2, tol=0.1), "order, tol"),
    (dict(order=None, tol=0.0), "tol"),
    (dict(method="magic"), "method"),
])
def test_bad_inputs_name_the_argument(kwargs, name):
    args = dict(A=np.diag([-1.0, -2.0, -3.0]), B=np.ones(3), C=np.ones(3), D=None, order=2)
    args.update(kwargs)
    with pytest.raises(ValueError, match=rf"^{name}:"):
        balanced_truncation(**args)
    if set(kwargs) <= {"A", "B", "C"}:
        with pytest.raises(ValueError, match=rf"^{name}:"):
            hankel_singular_values(args["A"], args["B"], args["C"])


@pytest.mark.skipif(importlib.util.find_spec("slycot") is not None, reason="slycot is installed")
def test_slycot_method_without_slycot():
    A, B, C = coupled_system(1, n=4)
    with pytest.raises(ImportError, match="slycot"):
        balanced_truncation(A, B, C, order=2, method="slycot")
    assert balanced_truncation(A, B, C, order=2, method="auto").method == "scipy"


def test_slycot_branch_is_wired(monkeypatch):
    # Without slycot, stand in for control.balred to check the call and the returned model.
    control = pytest.importorskip("control")
    import reduced.balance as bal
    calls = []

    def fake_balred(sys, orders, method):
        calls.append((sys.nstates, orders, method))
        return control.StateSpace(sys.A[:orders, :orders], sys.B[:orders], sys.C[:, :orders], sys.D)

    monkeypatch.setattr(bal, "_slycot_available", lambda: True)
    monkeypatch.setattr(control, "balred", fake_balred)
    A, B, C = coupled_system(1, n=6)
    red = balanced_truncation(A, B, C, tol=1e-2)   # "auto" picks slycot when it is there
    assert red.method == "slycot" and red.T is None and red.Ti is None
    assert calls == [(6, red.order, "truncate")]
    assert red.error_bound == pytest.approx(2 * red.hsv[red.order:].sum())


def test_to_statespace_dc_gain():
    control = pytest.importorskip("control")
    A, B, C = coupled_system(6)
    red = balanced_truncation(A, B, C, D=0.3, order=5)
    ss = red.to_statespace()
    assert isinstance(ss, control.StateSpace) and ss.nstates == 5
    dc_r = float(np.squeeze(control.dcgain(ss)))
    assert dc_r == pytest.approx(float(np.squeeze(red.D - red.C @ np.linalg.solve(red.A, red.B))), rel=1e-12)
    assert abs(dc_r - (0.3 - C @ np.linalg.solve(A, B))) <= red.error_bound   # |G(0) - G_r(0)| <= bound


def test_modal_form_preserves_transfer_function():
    A, B, C = coupled_system(7, n=8)
    Am, Bm, Cm = modal_form(A, B, C)
    lam = np.diag(Am)
    assert np.allclose(Am, np.diag(lam))
    assert np.all(np.diff(np.abs(lam)) > 0)                        # slowest first
    assert np.allclose(np.sort(lam), np.sort(np.diag(A)), rtol=1e-10)
    assert np.array_equal(Bm, np.ones((8, 1)))
    G = freqresp(A, B, C)
    assert np.abs(freqresp(Am, Bm, Cm) - G).max() <= 1e-9 * np.abs(G).max()


def test_modal_form_rejects_complex_eigenvalues():
    A = np.array([[-1.0, 2.0], [-2.0, -1.0]])
    with pytest.raises(ValueError, match=r"^A: .*complex"):
        modal_form(A, np.ones(2), np.ones(2))
