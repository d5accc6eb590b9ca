"""Recordings (dfa_model/io/recordings.py): every malformed input gets a one-line error naming
the file and row; documented handlings are stated in the notes; a simulation written by
`dfa simulate --out` reads back as a recording whose inferred protocol reproduces it."""
from __future__ import annotations

import numpy as np
import pytest

from dfa_model import preset, simulate
from dfa_model.io.parameters import preset_text
from dfa_model.io.recordings import RecordingError, read_csv, read_dataset
from dfa_model.waveforms import Protocol

V, F = 6000.0, 5.0


def columns(T=4.0, dt=1e-3, reset=1.0):
    t = np.round(np.arange(0.0, T + dt / 2, dt), 9)
    v = np.where(t < reset, np.where(np.floor(t * 60.0) % 2 == 0, V, -V), V)
    return {"time": t, "voltage": v, "force": np.full_like(t, F), "stroke": 8e-4 * (1 - np.exp(-t / 0.01))}


def write(path, cols, header=None, comment=True):
    names = header or list(cols)
    lines = ["# a test recording"] if comment else []
    lines.append(",".join(names))
    data = np.column_stack([cols[c] for c in cols])
    lines += [",".join(f"{x:.10g}" for x in row) for row in data]
    path.write_text("\n".join(lines) + "\n")
    return path


@pytest.fixture
def dataset(tmp_path):
    (tmp_path / "actuator.toml").write_text(preset_text("vshape-table1"))
    return tmp_path


def test_a_simulation_reads_back_and_its_protocol_reproduces_it(dataset):
    p = preset("vshape-table1")
    res = simulate(p, Protocol.reset_then_hold(V, 4.0, reset=1.0), load=F, t_eval=np.arange(0, 5.0005, 1e-3))
    res.to_csv(dataset / "sim.csv")
    d = read_dataset(dataset)
    r = d.recordings[0]
    assert r.amplitude == pytest.approx(V) and r.hold_voltage == pytest.approx(V)
    assert r.reset_end == pytest.approx(1.0, abs=1e-3)
    assert [s.label for s in r.protocol.stages] == ["reset", "hold"]
    assert r.load.F == pytest.approx(F)
    assert any("ignored column" in n for n in r.notes)          # the simulation's extra outputs
    again = simulate(p, r.protocol, load=r.load)
    # switches timed to the sample (1 ms): the stroke agrees to well under the sensor noise
    assert np.sqrt(np.mean((again.trace(r.t) - r.stroke) ** 2)) < 0.2e-6
    assert d.conditions() == {(V, F): [r]}


def test_synthetic_recording_levels_and_switches(tmp_path):
    r = read_csv(write(tmp_path / "a.csv", columns()))
    # it starts with the drive: the zero cannot be read at rest, and the report says so
    assert len(r.notes) == 1 and r.notes[0].startswith("no rest stretch before the drive")
    assert r.protocol.stages[0].label == "reset"
    # 60 stretches of 1/60 s in the 1 s reset, switch times within half a sample of k/60
    ts = r.protocol.stages[0].waveform.times
    assert len(ts) == 60
    assert np.max(np.abs(ts - np.arange(60) / 60.0)) <= 0.5e-3 + 1e-9


def test_a_rest_stretch_and_a_noisy_load_cell_need_no_note(tmp_path):
    """A 0 V stretch before the drive reads the zero (no note); a load cell's 0.02 N noise
    on 2 N (peak to peak ~0.16 N, beyond FORCE_TOL of the mean) is a constant load, while
    a real load step is a sampled load of the smoothed force."""
    c = columns()
    c["voltage"][:100] = 0.0
    rng = np.random.default_rng(0)
    c["force"] = np.full_like(c["time"], 2.0) + rng.normal(0.0, 0.02, c["time"].size)
    r = read_csv(write(tmp_path / "a.csv", c))
    assert r.notes == [] and r.load.F == pytest.approx(2.0, abs=1e-3)
    c["force"][2000:] += 1.0
    r = read_csv(write(tmp_path / "b.csv", c))
    assert "sampled load" in r.notes[0]
    f = r.load.F if callable(r.load.F) else None
    assert f is not None and abs(f(1.0) - 2.0) < 0.02 and abs(f(2.5) - 3.0) < 0.02


@pytest.mark.parametrize("mutate, pattern", [
    (lambda c: c.pop("stroke"), r"^a\.csv, row 2: missing column\(s\) stroke"),
    (lambda c: c["time"].__setitem__(100, c["time"][99]), r"^a\.csv, row 103: time 0\.099 s repeats"),
    (lambda c: c["time"].__setitem__(100, 0.05), r"^a\.csv, row 103: time 0\.05 s goes back from"),
    (lambda c: c["stroke"].__setitem__(7, np.nan), r"^a\.csv, row 10: stroke is nan \(values must be finite"),
    (lambda c: c["stroke"].__setitem__(slice(None), c["stroke"] * 1000), r"^a\.csv, row \d+: stroke 0\.8; SI units "
                                                                       r"\(m\) expected - this looks like millimetres"),
    (lambda c: c["voltage"].__setitem__(slice(None), c["voltage"] / 1000), r"^a\.csv, row \d+: voltage peaks at 6; .*"
                                                                         r"kilovolts"),
    (lambda c: c["voltage"].__setitem__(slice(2500, 2600), 3000.0), r"^a\.csv, row \d+: voltage 3000 V at 2\.5\d* s "
                                                                    r"is off every level.*contradicts itself"),
    (lambda c: c["voltage"].__setitem__(slice(3000, None), 0.0), r"^a\.csv: the voltage ends at 0 V"),
    (lambda c: c["time"].__iadd__(0.5), r"^a\.csv, row 3: time starts at 0\.5 s"),
])
def test_malformed_recordings_say_file_row_and_what(tmp_path, mutate, pattern):
    c = columns()
    mutate(c)
    with pytest.raises(RecordingError, match=pattern):
        read_csv(write(tmp_path / "a.csv", c))


def test_text_in_a_number_column(tmp_path):
    path = write(tmp_path / "a.csv", columns())
    lines = path.read_text().splitlines()
    lines[20] = lines[20].replace(lines[20].split(",")[3], "n/a")
    path.write_text("\n".join(lines))
    with pytest.raises(RecordingError, match=r"^a\.csv, row 21: stroke is 'n/a', not a number"):
        read_csv(path)


def test_empty_file_and_short_file(tmp_path):
    (tmp_path / "e.csv").write_text("# only a comment\n")
    with pytest.raises(RecordingError, match=r"^e\.csv: empty"):
        read_csv(tmp_path / "e.csv")
    c = {k: v[:5] for k, v in columns().items()}
    with pytest.raises(RecordingError, match=r"^s\.csv: 5 data rows, at least 10"):
        read_csv(write(tmp_path / "s.csv", c))


def test_gaps_are_kept_and_stated(tmp_path):
    c = {k: np.delete(v, np.s_[2000:2200]) for k, v in columns().items()}
    r = read_csv(write(tmp_path / "g.csv", c))
    assert len(r.t) == len(columns()["time"]) - 200
    assert any("1 gap(s)" in n and "1.999-2.2 s" in n for n in r.notes), r.notes


def test_varying_force_is_a_sampled_load(tmp_path):
    c = columns()
    c["force"] = F + 1.0 * (c["time"] > 2.0)
    r = read_csv(write(tmp_path / "f.csv", c))
    assert any("sampled load" in n for n in r.notes)
    assert r.load.piecewise(4.0)(np.array([1.0, 3.0])) == pytest.approx([F, F + 1.0])


def test_dataset_folder_errors(tmp_path):
    with pytest.raises(RecordingError, match="not a folder"):
        read_dataset(tmp_path / "nope")
    with pytest.raises(RecordingError, match="no actuator.toml"):
        read_dataset(tmp_path)
    (tmp_path / "actuator.toml").write_text(preset_text("vshape-table1"))
    with pytest.raises(RecordingError, match=r"no recordings \(\*\.csv\)"):
        read_dataset(tmp_path)
    (tmp_path / "actuator.toml").write_text("layout = 'v-shaped'\n")
    write(tmp_path / "a.csv", columns())
    with pytest.raises(RecordingError, match="^actuator.toml: "):
        read_dataset(tmp_path)


def test_stroke_beyond_the_actuators_reach(dataset):
    # 8 mm: beyond Table 1's reach (1.5 x_e = 6.8 mm) but not by the factor 1000 of a
    # millimetre column (0.8 there: test_malformed_recordings_say_file_row_and_what)
    c = columns()
    c["stroke"] = c["stroke"] * 10.0
    write(dataset / "a.csv", c)
    with pytest.raises(RecordingError, match=r"^a\.csv, row \d+: stroke 0\.008; SI units \(m\) expected, above the "
                                             r"actuator's reach"):
        read_dataset(dataset)


# ---------------------------------------------------------------- synthetic recordings
def test_synthetic_dataset_is_measured_like_a_rig(tmp_path):
    from dfa_model.io.synthetic import Measurement, generate_dataset, scaled_resistivity
    truth = preset("vshape-table1").replace(N=41)
    nominal = truth.replace(rho_l=3e12)
    meas = Measurement(noise=2e-6, quantum=0.5e-6, offset=5e-6, rho_spread=0.05)
    folder = tmp_path / "ds"
    drawn = generate_dataset(folder, truth, nominal, conditions=[(6000, 3), (7000, 5)], repetitions=2, reset=1.0,
                             hold=4.0, measurement=meas, seed=3, manifest=tmp_path / "manifest.json")
    assert sorted(f.name for f in folder.iterdir()) == ["V6kV_F3N_r1.csv", "V6kV_F3N_r2.csv", "V7kV_F5N_r1.csv",
                                                       "V7kV_F5N_r2.csv", "actuator.toml"]
    d = read_dataset(folder)
    assert d.params.rho_l == 3e12                       # the nominal value, not the truth
    assert list(d.conditions()) == [(6000.0, 3.0), (7000.0, 5.0)]
    factors = [r["rho_factor"] for r in drawn["recordings"]]
    assert len(set(factors)) == 4 and all(0.8 < f < 1.25 for f in factors)
    for rec, dr in zip(d.recordings, drawn["recordings"]):
        assert rec.name == dr["recording"] and rec.notes == []
        assert np.allclose(rec.stroke / 0.5e-6, np.round(rec.stroke / 0.5e-6), atol=1e-6)   # quantized
        # at the truth's tolerance (synthetic.TRUTH_RTOL: at the default 1e-4 the integrator's
        # own error moved a hold's mean by 0.1 um)
        clean = simulate(scaled_resistivity(truth, dr["rho_factor"]), rec.protocol, load=rec.load, rtol=1e-7)
        resid = rec.stroke - clean.trace(rec.t) - dr["offset"]
        # the recorder starts 0.1 s before the drive, at rest: the sensor's zero shows there
        pre = rec.t < dr["pretrigger"]
        assert pre.sum() >= 99 and np.all(clean.trace(rec.t)[pre] == 0.0)
        # the trigger read off the voltage channel is timed to ~0.05 ms (within the sample
        # that brackets it); the zipping transient right after it moves that much by up to
        # ~20 um: the noise statistics are checked from 30 ms on
        resid = resid[(rec.t < dr["pretrigger"]) | (rec.t > dr["pretrigger"] + 0.03)]
        # white noise of 2 um plus the quantization's 0.5 / sqrt(12) um
        assert np.std(resid) == pytest.approx(np.hypot(2e-6, 0.5e-6 / np.sqrt(12)), rel=0.08)
        assert abs(np.mean(resid)) < 0.2e-6
        assert abs(np.corrcoef(resid[:-1], resid[1:])[0, 1]) < 0.06   # white


def test_lab_exports_a_bom_a_semicolon_and_a_units_row(tmp_path):
    """A spreadsheet's byte-order mark, a semicolon delimiter and a units row in lab units
    read as the same recording as the plain SI file; an unknown unit is one line naming
    the column and the units allowed."""
    c = columns()
    ref = read_csv(write(tmp_path / "si.csv", c))
    lines = ["time;voltage;force;stroke", "ms;kV;N;mm"]
    lines += [f"{t * 1e3:.6g};{v / 1e3:.10g};{f:.10g};{x * 1e3:.10g}"
              for t, v, f, x in zip(c["time"], c["voltage"], c["force"], c["stroke"])]
    path = tmp_path / "lab.csv"
    path.write_bytes(b"\xef\xbb\xbf" + ("\n".join(lines) + "\n").encode())
    r = read_csv(path)
    assert np.allclose(r.t, ref.t) and np.allclose(r.voltage, ref.voltage) and np.allclose(r.stroke, ref.stroke)
    assert r.hold_voltage == pytest.approx(ref.hold_voltage) and any("units row" in n for n in r.notes)
    path.write_text("\n".join(["time;voltage;force;stroke", "ms;kV;lbf;mm"] + lines[2:]) + "\n")
    with pytest.raises(RecordingError, match=r"^lab\.csv, row 2: force in unit 'lbf' \(units row\); allowed: n, mn"):
        read_csv(path)


def test_repetitions_ending_on_either_polarity_are_one_condition(dataset):
    """A polarity inversion's recording ends on +V or -V by the phase it stops at, and the
    model is odd in V: repetitions that end on opposite polarities are one condition
    (a split had held out a single recording of a 1 Hz inversion dataset, at "-5990 V")."""
    t = np.round(np.arange(0.0, 2.0 + 5e-4, 1e-3), 9)
    for i, (amp, end) in enumerate([(V, 0.0), (V, 0.5), (V + 10.0, 0.25), (7000.0, 0.0), (7000.0, 0.5)]):
        v = np.where(np.floor((t + end) * 2.0) % 2 == 0, amp, -amp)        # 1 Hz, shifted phase
        cols = {"time": t, "voltage": v, "force": np.full_like(t, F), "stroke": 6e-4 * (1 - np.exp(-t / 0.01))}
        write(dataset / f"r{i}.csv", cols)
    ds = read_dataset(dataset)
    ends = {r.name: np.sign(r.hold_voltage) for r in ds.recordings}
    assert len(set(ends.values())) == 2                 # both polarities among the hold levels
    groups = ds.conditions()
    assert sorted(groups) == [(6000.0, F), (7000.0, F)]
    assert sorted(len(v) for v in groups.values()) == [2, 3]
