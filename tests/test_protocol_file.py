"""The protocol file (dfa_model/io/protocol_file.py): one language for a drive. Round trips
are exact, every stage kind and the load are expressible, bad input is one line naming
the file, stage and key, and the waveforms mean what the README says (duty, ramps
centred on their instants, the charge-balanced start)."""
from __future__ import annotations

import dataclasses
import json
import subprocess
import sys

import numpy as np
import pytest

from dfa_model import DC, Bipolar, Load, Protocol, Sampled, Stage, Unipolar, WaveformError, simulate
from dfa_model.waveforms import balanced_phase, charge_phase_offset

V = 6000.0


def _every_kind(tmp_path):
    (tmp_path / "sig.csv").write_text("# a user signal\ntime,voltage\n0,0\n0.5,3000\n1.0,-2000\n")
    return Protocol([
        Stage(Bipolar(V, 30.0, 1.0), 0.5, "reset"),
        Stage(Bipolar(V, 2.3, 0.8, slew_rate=3e6, phase=0.1, positive_share=0.45), 1.7, "inv"),
        Stage(Unipolar(-V, 5.0, 0.3, slew_rate=2e7, phase="balanced"), 0.9, "pulses"),
        Stage(Sampled([0.0, 0.2, 0.2, 0.7], [0.0, 4000.0, 5000.0, 1000.0], hold=True), 0.9, "user"),
        Stage(DC(V), 2.0, "hold")],
        load=Load(Sampled([0.0, 1.0, 6.0], [2.0, 5.0, 4.0], name="force"), k_load=120.0))


def _same_drive(a: Protocol, b: Protocol):
    pa, pb = a.piecewise(), b.piecewise()
    for name in ("t", "v0", "slope"):
        assert np.array_equal(getattr(pa, name), getattr(pb, name)), name
    assert [s.label for s in a.stages] == [s.label for s in b.stages]
    la, lb = a.load.piecewise(a.duration), b.load.piecewise(b.duration)
    assert np.array_equal(la.t, lb.t) and np.array_equal(la.v0, lb.v0) and a.load.k_load == b.load.k_load


def test_round_trip_is_exact_for_every_kind(tmp_path):
    p = _every_kind(tmp_path)
    _same_drive(p, Protocol.from_toml(p.to_toml()))
    written = p.save(tmp_path / "drive.toml", header="a test")
    assert written == [tmp_path / "drive.toml"]
    q = Protocol.from_toml(tmp_path / "drive.toml")
    _same_drive(p, q)
    text = (tmp_path / "drive.toml").read_text()
    assert text.startswith("# a test\n") and "[load]" in text and 'waveform = "sampled"' in text


def test_sampled_stage_from_a_file_and_long_signals_beside_the_file(tmp_path):
    (tmp_path / "sig.csv").write_text("# comment\ntime,voltage,extra\n0,0,1\n0.5,3000,1\n1.0,-2000,1\n")
    (tmp_path / "d.toml").write_text('[[stage]]\nwaveform = "sampled"\nfile = "sig.csv"\n')
    p = Protocol.from_toml(tmp_path / "d.toml")
    assert p.duration == 1.0          # the last sample's time
    assert p.voltage(np.array([0.25, 0.75])) == pytest.approx([1500.0, 500.0])
    t = np.linspace(0, 2, 1001)
    long = Protocol([Stage(Sampled(t, 5000 * np.sin(7 * t)), 2.0, "hold")], load=Load(Sampled(t, 3 + t, name="force")))
    written = long.save(tmp_path / "long.toml")
    assert [w.name for w in written] == ["long.toml", "long.stage1.csv", "long.load.csv"]
    _same_drive(long, Protocol.from_toml(tmp_path / "long.toml"))


BAD = [
    ('[[stage]]\nwaveform = "dc"\nvoltage = 6000\nfrequency = 3.0\nduration = 1\n', "stage 1: frequency: does not apply"),
    ('[[stage]]\nwaveform = "dc"\nvoltage = 6000\nduration = -1\n', "stage 1: duration: got -1"),
    ('[[stage]]\nwaveform = "dc"\nvoltag = 6000\nduration = 1\n', "stage 1: voltag: unknown key"),
    ('[[stage]]\nname = "h"\nwaveform = "sampled"\nfile = "nope.csv"\n', "stage 1 (h): file: "),
    ('[[stage]]\nwaveform = "square"\nvoltage = 1\nduration = 1\n', "stage 1: waveform: got 'square'"),
    ('[[stage]]\nwaveform = "bipolar"\nvoltage = 6000\nduration = 1\n', "stage 1: frequency: required"),
    ('[[stage]]\nwaveform = "bipolar"\nvoltage = 6000\nfrequency = 100\nslew_rate = 1e6\nduration = 1\n',
     "stage 1: slew_rate: ramps of up to 0.012 s"),
    ('[[stage]]\nwaveform = "bipolar"\nvoltage = 6000\nfrequency = 1\nphase = 1.0\nduration = 1\n', "stage 1: phase"),
    ('[[stage]]\nwaveform = "bipolar"\nvoltage = "6 kV"\nfrequency = 1\nduration = 1\n', "stage 1: voltage: got '6 kV'"),
    ('[[stage]]\nwaveform = "unipolar"\nvoltage = 6000\nfrequency = 1\npositive_share = 0.4\nduration = 1\n',
     "stage 1: positive_share: does not apply to a unipolar stage"),
    ('[[stage]]\nwaveform = "sampled"\ntimes = [0, 1]\nvalues = [0]\n', "stage 1: values: 1 values for 2 times"),
    ('[[stage]]\nwaveform = "dc"\nvoltage = 6000\nduration = 1\n[load]\nforce = 5\ntimes = [0]\nvalues = [1]\n',
     "load: force: give a constant force or a sampled one"),
    ('[[stage]]\nwaveform = "dc"\nvoltage = 6000\nduration = 1\n[load]\nforse = 5\n', "load: forse: unknown key"),
    ('stages = 1\n', "stages: unknown key"),
    ('[[stage]\n', "not valid TOML"),
    ('# nothing\n', "stage: no stages"),
]


@pytest.mark.parametrize("text, message", BAD)
def test_bad_protocol_file_is_one_line_naming_file_stage_and_key(tmp_path, text, message):
    path = tmp_path / "drive.toml"
    path.write_text(text)
    with pytest.raises(WaveformError) as exc:
        Protocol.from_toml(path)
    msg = str(exc.value)
    assert msg.startswith(str(path)) and message in msg and "\n" not in msg, msg


def test_bad_protocol_file_in_the_cli_exits_2_with_one_line(tmp_path):
    path = tmp_path / "drive.toml"
    path.write_text(BAD[0][0])
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--protocol",
                        str(path)], capture_output=True, text=True)
    assert r.returncode == 2, r.stderr
    assert r.stderr.strip().count("\n") == 0 and "frequency: does not apply to a dc stage" in r.stderr
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--protocol",
                        str(tmp_path / "missing.toml")], capture_output=True, text=True)
    assert r.returncode == 2 and "missing.toml: protocol file not found" in r.stderr
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--protocol",
                        str(path), "--duration", "3"], capture_output=True, text=True)
    assert r.returncode == 2 and "remove --duration" in r.stderr


# ------------------------------------------------------------ what the waveforms mean
def _time_shares(wave, periods=3, n=600_001):
    T = 1 / wave.frequency
    t = np.linspace(0.0, periods * T, n)[:-1]
    v = wave.piecewise(periods * T)(t)
    return t, v


@pytest.mark.parametrize("duty", [1.0, 0.7, 0.3])
def test_duty_is_the_share_of_each_half_period_at_full_voltage(duty):
    t, v = _time_shares(Bipolar(V, 4.0, duty))
    assert np.mean(np.abs(v) == V) == pytest.approx(duty, abs=1e-5)
    assert np.mean(v == V) == pytest.approx(duty / 2, abs=1e-5)
    t, v = _time_shares(Unipolar(V, 4.0, duty))
    assert np.mean(v == V) == pytest.approx(duty, abs=1e-5)


@pytest.mark.parametrize("wave", [Bipolar(V, 2.0, 1.0, slew_rate=4e6), Bipolar(V, 2.0, 0.6, slew_rate=4e5),
                                  Bipolar(V, 3.0, 0.95, slew_rate=1.1e5), Bipolar(V, 2.0, 1.0, slew_rate=4e6,
                                                                                   positive_share=0.4),
                                  Unipolar(V, 5.0, 0.5, slew_rate=1e6)])
def test_ramps_are_centred_on_the_ideal_instants(wave):
    """A ramped wave has the period mean and the slope bound of its ideal twin, and moves
    at the slew rate where it moves."""
    ideal = dataclasses.replace(wave, slew_rate=None)
    t, v = _time_shares(wave)
    _, vi = _time_shares(ideal)
    assert np.mean(v) == pytest.approx(np.mean(vi), abs=2e-4 * V)
    pw = wave.piecewise(3 / wave.frequency)
    assert np.max(np.abs(pw.slope)) == pytest.approx(wave.slew_rate, rel=1e-9)
    assert set(np.round(np.abs(pw.slope[pw.slope != 0]) / wave.slew_rate, 9)) == {1.0}


def test_a_short_dead_time_merges_its_two_ramps_continuously():
    """Below the threshold where the 0 V gap is shorter than its two half ramps, the
    inversion is one ramp through 0 centred on the gap: the waveform is continuous in duty
    across that threshold."""
    f, slew = 2.0, 2e5            # a switch between 0 and V takes V / slew = 30 ms
    r = V / slew
    d_star = 1 - 2 * r * f        # (1 - d) T / 2 = r
    t = np.linspace(0, 1 / f, 200_001)
    below = Bipolar(V, f, d_star + 1e-7, slew_rate=slew).piecewise(1 / f)(t)
    above = Bipolar(V, f, d_star - 1e-7, slew_rate=slew).piecewise(1 / f)(t)
    assert np.max(np.abs(below - above)) < 1e-3 * V


@pytest.mark.parametrize("wave", [Bipolar(V, 2.0), Bipolar(V, 2.0, 1.0, slew_rate=4e6),
                                  Bipolar(V, 0.3, 0.6, slew_rate=2e5), Bipolar(-V, 1.0, 1.0, positive_share=0.4),
                                  Unipolar(V, 5.0, 0.3), Bipolar(V, 3.0, 0.95, slew_rate=1.1e5)])
def test_balanced_start_has_no_charge_offset(wave):
    """At the balanced phase the period mean of g = int (V - <V>) dt from the start is 0
    (exact: g is piecewise quadratic), where a phase-0 start carries an offset ~ V T / 4."""
    T = 1 / wave.frequency
    assert abs(charge_phase_offset(dataclasses.replace(wave, phase=0.0))) > 1e-3 * abs(wave.V) * T
    bal = dataclasses.replace(wave, phase="balanced")
    assert 0.0 <= bal.phase < 1.0 and bal.phase == balanced_phase(wave)
    assert abs(charge_phase_offset(bal)) < 1e-9 * abs(wave.V) * T


def test_symmetric_inversion_starts_a_quarter_period_in():
    assert balanced_phase(Bipolar(V, 7.0)) == pytest.approx(0.25, abs=1e-14)
    assert balanced_phase(Bipolar(V, 7.0, 1.0, slew_rate=1e6)) == pytest.approx(0.25, abs=1e-14)


# ------------------------------------------------------------ the words of a run
def test_drift_is_stroke_lost_and_drift_rate_its_rate(vshape81):
    """Unipolar pulses lose stroke period after period: drift (m) and drift_rate (m/s) are
    both positive; drift is x_static minus the last period's mean; the old call
    drift(period) fails saying what to call."""
    r = simulate(vshape81, Protocol.single(Unipolar(V, 1.0, 0.5), 12.0), load=5.0)
    T = 1.0
    c = r.trace.mean(r.trace.t1 - T, r.trace.t1)
    assert r.period == T and r.end_stroke == pytest.approx(c, rel=1e-12)
    assert r.drift == pytest.approx(r.x_static - c, rel=1e-12) and r.drift > 0
    assert r.drift_rate() > 0
    with pytest.raises(TypeError, match="drift_rate"):
        r.drift(T)
    dc = simulate(vshape81, Protocol.dc(V, 10.0), load=5.0)
    assert dc.period is None and dc.drift == pytest.approx(dc.x_static - dc.final_stroke)
    with pytest.raises(ValueError, match="drift_rate: the run's last stage is not periodic"):
        dc.drift_rate()


def test_simulate_takes_the_protocol_files_load_unless_given(vshape81, tmp_path):
    p = Protocol.dc(V, 1.0)
    p.load = Load(3.0)
    a, b = simulate(vshape81, p), simulate(vshape81, p, load=3.0)
    assert np.array_equal(a.x, b.x) and a.F[0] == 3.0
    c = simulate(vshape81, p, load=5.0)
    assert c.F[0] == 5.0


def test_input_power_of_hard_switching_is_4fCV2(vshape81):
    """Ideal inversion books the source's loss of each jump: the full model's input power
    is the hard-switched dissipation 4 f C V^2 (C at the held stroke) plus a little
    leakage; with slow ramps the charge comes back and it is far smaller."""
    from reduced.design import device_capacitance
    f = 3.0
    ideal = simulate(vshape81, Protocol.single(Bipolar(V, f, phase="balanced"), 5.0), load=5.0, energy=True)
    C = device_capacitance(vshape81, ideal.end_stroke, V)
    assert ideal.input_power() == pytest.approx(4 * f * C * V * V, rel=0.02)
    ramped = simulate(vshape81, Protocol.single(Bipolar(V, f, slew_rate=4e7, phase="balanced"), 5.0), load=5.0,
                      energy=True)
    assert 0 < ramped.input_power() < 0.05 * ideal.input_power()


def test_simulate_json_reports_the_words(tmp_path):
    path = tmp_path / "d.toml"
    Protocol([Stage(Bipolar(V, 2.0, slew_rate=4e7, phase="balanced"), 3.0, "hold")], load=Load(5.0)).save(path)
    r = subprocess.run([sys.executable, "-m", "dfa_model.cli", "simulate", "--preset", "vshape-table1", "--set", "N=21",
                        "--protocol", str(path), "--json"], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    assert {"static_stroke", "final_stroke", "unzipping_speed", "x_static", "end_stroke", "drift", "period", "ripple",
            "drift_rate", "input_power"} <= set(out)
    assert out["period"] == 0.5 and out["ripple"] > 0 and abs(out["drift"]) < 0.1 * out["x_static"]
