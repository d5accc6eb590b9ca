"""The lattice's long-step method, ROS34PW2 (dfa_model.numerics.surrogate_kernel): its
transformed coefficients derived again from the published tableau, its order and
stability on the scalar test equation; and the runs its long steps and the step bound
serve - a slow creep whose records stay within the tolerance of the stroke's balance
and of the full model, and a snap off the stop taken in steps the tables' grid can
follow."""
import warnings

import numpy as np
import pytest

import reduced
from dfa_model import Bipolar, PhysicsWarning, Protocol, preset, simulate
from dfa_model.numerics import surrogate_kernel as sk
from reduced.compare import compare

warnings.simplefilter("ignore", PhysicsWarning)

# Rang & Angermann (2005), ROS34PW2: alpha_ij, gamma_ij (gamma on the diagonal), b, b^
GAM = 0.43586652150845900
ALPHA = np.array([[0, 0, 0, 0], [0.87173304301691801, 0, 0, 0],
                  [0.84457060015369423, -0.11299064236484185, 0, 0], [0, 0, 1.0, 0]])
GAMMA = np.array([[GAM, 0, 0, 0], [-0.87173304301691801, GAM, 0, 0],
                  [-0.90338057013044082, 0.054180672388095326, GAM, 0],
                  [0.24212380706095346, -1.2232505839045147, 0.54526025533510214, GAM]])
B = np.array([0.24212380706095346, -1.2232505839045147, 1.5452602553351020, GAM])
B_HAT = np.array([0.37810903145819369, -0.096042292212423178, 0.5, 0.21793326075422950])


def _kernel_tableau():
    A = np.zeros((4, 4))
    A[1, 0] = sk.R_A21
    A[2, :2] = sk.R_A31, sk.R_A32
    A[3, :3] = sk.R_A41, sk.R_A42, sk.R_A43
    C = np.zeros((4, 4))
    C[1, 0] = sk.R_C21
    C[2, :2] = sk.R_C31, sk.R_C32
    C[3, :3] = sk.R_C41, sk.R_C42, sk.R_C43
    M = np.array([sk.R_M1, sk.R_M2, sk.R_M3, sk.R_M4])
    E = np.array([sk.R_E1, sk.R_E2, sk.R_E3, sk.R_E4])
    return A, C, M, E


def test_the_kernels_coefficients_are_the_papers_transformed():
    """A = alpha G^-1, C = diag(1/gam) - G^-1, M = b G^-1, E = (b - b^) G^-1 (Hairer &
    Wanner IV.7), the strictly lower parts; the method is stiffly accurate (M is A's last
    row and 1)."""
    Gi = np.linalg.inv(GAMMA)
    A, C, M, E = _kernel_tableau()
    assert sk.R_GAM == GAM
    np.testing.assert_allclose(A, np.tril(ALPHA @ Gi, -1), atol=1e-14)
    np.testing.assert_allclose(C, np.tril(np.diag(np.full(4, 1 / GAM)) - Gi, -1), atol=1e-14)
    np.testing.assert_allclose(M, B @ Gi, atol=1e-14)
    np.testing.assert_allclose(E, (B - B_HAT) @ Gi, atol=1e-14)
    np.testing.assert_allclose(M[:3], A[3, :3], atol=1e-14)


def _R(z, weights):
    """The stability function on y' = lam y, z = h lam, of the kernel's stage recursion
    (k_i = gam (lam y_i + sum C_ij k_j) / (1 - gam z), y_i = 1 + h sum A_ij k_j), h = 1."""
    A, C, M, _ = _kernel_tableau()
    k = np.zeros(4, dtype=complex)
    for i in range(4):
        yi = 1.0 + A[i, :i] @ k[:i]
        k[i] = GAM * (z * yi + C[i, :i] @ k[:i]) / (1.0 - GAM * z)
    return 1.0 + weights @ k


def test_order_three_and_l_stable_on_the_test_equation():
    """R(z) - e^z = O(z^4) (order 3); the embedded solution is of order 2 (its error
    estimate O(z^3)); R -> 0 far into the left half plane (L-stable: a long step damps the
    stroke's fast relaxation instead of carrying it on)."""
    _, _, M, E = _kernel_tableau()
    d1, d2 = abs(_R(1e-2, M) - np.exp(1e-2)), abs(_R(5e-3, M) - np.exp(5e-3))
    assert d1 / d2 == pytest.approx(16.0, rel=0.05)        # local error z^4: order 3
    e1, e2 = abs(_R(1e-2, E) - 1.0), abs(_R(5e-3, E) - 1.0)
    assert e1 / e2 == pytest.approx(8.0, rel=0.05)
    for z in (-1e3, -1e5, -1e3 + 1e3j):
        assert abs(_R(z, M)) * abs(z) < 3.0                # R(z) = O(1/z): R(inf) = 0
    for z in (-0.5, -5.0, -50.0, 1j, -1 + 3j):
        assert abs(_R(z, M)) <= 1.0


@pytest.fixture(scope="module")
def table1():
    return preset("vshape-table1")


def test_a_creep_stays_on_the_balance_and_on_the_full_model(table1):
    """Under DC the front creeps (tens of um/s) while the massless stroke relaxes in
    milliseconds: in a reset's 20 s hold, taken in steps of about a second, each record's
    force balance is off by less than the tolerance's stroke (0.05 % of x + x_e) times
    the stroke's stiffness (up to 2.0 um here; 0.9 um with ode23s's shorter steps), and
    the trajectory is the full model's (the records' stroke within 3 um)."""
    s = reduced.lattice(table1)
    proto = Protocol.reset_then_hold(6000.0, 20.0)
    r = s.simulate(proto, 5.0)
    full = simulate(table1, proto, load=5.0)
    m = r.t > 4.0
    assert m.sum() >= 10
    k_stroke = 400.0 * table1.b            # the stroke's rate constant (about 250-480 1/s here) x b
    off = np.abs(r.Fe[m] - r.F[m]) / k_stroke
    assert off.max() < s.rtol * (r.x[m].max() + s.x_e)
    assert np.abs(np.interp(r.t[m], full.t, full.x) - r.x[m]).max() < 3e-6


def test_a_snap_off_the_stop_is_followed_by_the_grid(table1):
    """A 10 Hz bipolar train (duty 0.4) at 6 kV, 4 N: each half period the stroke snaps
    from 0 to over 1 mm. Taken in one 1.2 ms step of 2.6 of the stroke's time constants
    (estimated within the tolerance by either method) it passed 80 um off the full model
    and the run's RMS error was 0.87 % of the range; within LAT_CELLS grid intervals a
    step it is 0.23 %."""
    s = reduced.lattice(table1)
    c = compare(s, Protocol.single(Bipolar(6000.0, 10.0, 0.4), 10.0), 4.0)
    assert c["relative_rms_error"] < 5e-3
