"""Waveforms, user signals and loads."""
import numpy as np
import pytest

from dfa_model import DC, Bipolar, Load, Protocol, Sampled, Unipolar, WaveformError, from_function, simulate
from dfa_model.physics.statics import equilibrium_stroke


def test_square_waves_levels_and_switch_count():
    pw = Bipolar(6000, 30.0).piecewise(3.0)
    assert len(pw.t) - 1 == 180                          # 180 half periods: the reset's switches
    assert set(np.unique(pw.v0)) == {-6000.0, 6000.0}
    pw = Bipolar(6000, 10.0, duty=0.5).piecewise(0.1)
    assert list(pw.v0) == [6000.0, 0.0, -6000.0, 0.0]
    pw = Unipolar(6000, 2.0, 0.25).piecewise(1.0)
    assert np.allclose(pw.t, [0, 0.125, 0.5, 0.625, 1.0]) and list(pw.v0) == [6000, 0, 6000, 0]


@pytest.mark.parametrize("make,needle", [
    (lambda: Bipolar(6000, -1), "frequency"),
    (lambda: Bipolar(6000, 10, duty=1.5), "duty"),
    (lambda: DC(float("nan")), "voltage"),
    (lambda: Sampled([0, 1], [0, np.inf]), "finite"),
    (lambda: Sampled([0, 2, 1], [0, 1, 2]), "non-decreasing"),
    (lambda: Protocol.dc(6000, 0.0), "duration"),
    (lambda: from_function(lambda t: 1 / 0, 1.0), "ZeroDivisionError"),
])
def test_bad_waveforms_name_the_field(make, needle):
    with pytest.raises(WaveformError, match=needle):
        make()


def test_sampled_signal_equals_equivalent_builtin(vshape81):
    """A user table that steps like a unipolar pulse train gives the same stroke."""
    t = np.linspace(0, 4, 401)
    a = simulate(vshape81, Unipolar(6000, 0.5, 0.5), duration=4.0, load=5.0, t_eval=t)
    table = Sampled([0, 1, 1, 2, 2, 3, 3, 4], [6000, 6000, 0, 0, 6000, 6000, 0, 0])
    b = simulate(vshape81, table, duration=4.0, load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - b.x)) < 1e-6 * np.max(a.x)
    held = Sampled([0, 1, 2, 3], [6000, 0, 6000, 0], hold=True)
    c = simulate(vshape81, held, duration=4.0, load=5.0, t_eval=t)
    assert np.max(np.abs(a.x - c.x)) < 1e-6 * np.max(a.x)


def test_callable_ramp_is_sampled_linearly(vshape81):
    ramp = from_function(lambda t: 6000 * min(t / 0.5, 1.0), 2.0, dt=0.01)
    r = simulate(vshape81, ramp, duration=2.0, load=5.0, t_eval=np.linspace(0, 2, 201))
    assert np.allclose(r.V, 6000 * np.minimum(r.t / 0.5, 1.0), atol=1e-6)
    assert np.all(np.diff(r.x[r.t < 0.4]) >= -1e-12)          # zips progressively


def test_load_as_function_of_time_and_spring(vshape81):
    # force stepping from 5 N to 7 N: the stroke follows the static equilibria
    load = Load(Sampled([0, 1, 1, 2], [5, 5, 7, 7]))
    r = simulate(vshape81, Protocol.single(Bipolar(6000, 200.0), 2.0), load=load, t_eval=np.array([0.9, 1.9]))
    for x, F in zip(r.x, (5.0, 7.0)):
        assert abs(x / equilibrium_stroke(vshape81, 6000, F) - 1) < 2e-3
    # a spring load k x adds to the force: equilibrium where F_e(x) = F0 + k x
    k = 2000.0
    r = simulate(vshape81, Protocol.single(Bipolar(6000, 200.0), 0.5), load=Load(3.0, k_load=k))
    x_eq = equilibrium_stroke(vshape81.replace(k=k), 6000, 3.0)
    assert abs(r.x[-1] / x_eq - 1) < 2e-3
    assert r.x[-1] < equilibrium_stroke(vshape81, 6000, 3.0)


def test_segment_key_names_every_field_and_refuses_what_it_cannot_hash():
    """The input segments' cache key (waveforms.segment_key): equal for equal fields, apart
    for a field's value or name, None for a value it cannot hash or a waveform it does not
    know."""
    from dfa_model.waveforms import segment_key
    k = segment_key(Protocol.reset_then_hold(6000.0, 20.0), Load(5.0))
    assert k == segment_key(Protocol.reset_then_hold(6000.0, 20.0), Load(5.0)) and hash(k) == hash(k)
    assert k != segment_key(Protocol.reset_then_hold(6000.0, 21.0), Load(5.0))
    assert k != segment_key(Protocol.reset_then_hold(6000.0, 20.0), Load(4.0))
    p = Protocol.reset_then_hold(6000.0, 20.0)
    p.stages[0].waveform.duty = 0.9
    assert segment_key(p, Load(5.0)) != k
    p.stages[0].waveform.duty = [1.0]            # not hashable: not cached, not an error
    assert segment_key(p, Load(5.0)) is None
    # the same values under other names are another key
    a, b = Protocol.dc(6000.0, 1.0), Protocol.dc(6000.0, 1.0)
    a.stages[0].waveform.x = 1.0
    b.stages[0].waveform.y = 1.0
    assert segment_key(a, Load(0.0)) != segment_key(b, Load(0.0))
