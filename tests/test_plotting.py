"""dfa simulate --plot / Result.plot: every quantity on an axis that shows it, and the
CSV says what its zipping_angle is."""
import numpy as np
import pytest

from dfa_model import Protocol, simulate
from dfa_model.cli import main


@pytest.fixture(scope="module")
def baseline():
    from dfa_model import preset
    return simulate(preset("vshape-table1"), Protocol.reset_then_hold(6000, hold=20), load=5.0,
                    t_eval=np.linspace(0, 23, 2301))


def test_force_axis_is_not_scaled_by_the_zipping_spike(baseline):
    import matplotlib.pyplot as plt
    fig = baseline.plot(source="preset vshape-table1")
    try:
        v_ax, x_ax, f_ax, i_ax = fig.axes[:4]
        lo, hi = f_ax.get_ylim()
        assert baseline.Fe.max() > 2 * 5.0            # the spike at t = 0 (the blocking force)
        assert lo < 5.0 < hi and hi - lo < 2.0        # the load and the balance stay readable
        assert "off scale" in f_ax.get_title(loc="right")
        assert "current" in i_ax.get_ylabel()
        ilo, ihi = i_ax.get_ylim()                    # the hold's leakage current (tens of nA) is visible
        assert "nA" in i_ax.get_ylabel() and ihi - ilo < 1e3
        # the 30 Hz reset is a band, not 180 drawn switches; each stage is named
        assert len(v_ax.collections) == 1 and all(len(line.get_xdata()) < 10 for line in v_ax.lines)
        names = [t.get_text() for t in v_ax.texts]
        assert any(t.startswith("reset (3 s): bipolar") for t in names)
        assert any(t.startswith("hold (20 s): DC 6 kV") for t in names)
        title = fig._suptitle.get_text()
        assert "preset vshape-table1" in title and "load 5 N" in title and "6 kV" in title
    finally:
        plt.close(fig)


def test_slow_square_wave_is_drawn(vshape81):
    import matplotlib.pyplot as plt
    from dfa_model import Unipolar
    res = simulate(vshape81, Protocol.single(Unipolar(6000, 0.5, 0.5), 4.0), load=5.0)
    fig = res.plot()
    try:
        v_ax = fig.axes[0]
        assert not v_ax.collections and max(len(line.get_xdata()) for line in v_ax.lines) >= 8
    finally:
        plt.close(fig)


@pytest.mark.parametrize("name, says", [("vshape-table1", "Eq. 18"), ("peano-fig10", "half the curvature angle")])
def test_csv_header_says_what_zipping_angle_is(tmp_path, name, says):
    out = tmp_path / "r.csv"
    assert main(["simulate", "--preset", name, "--voltage", "6000", "--duration", "0.05", "--out", str(out)]) in (0, None)
    head = [ln for ln in out.read_text().splitlines() if ln.startswith("#")]
    assert any(ln.startswith("# zipping_angle:") and says in ln for ln in head)
