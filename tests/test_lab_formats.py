"""Lab recording formats (dfa_model/io/recordings.py): dataset.toml's column names and units,
HDF5 and TDMS, the size limit, CRLF and csv's field limit. A simulated recording written in
each format reads back as the SI original with the same protocol; every failure is one
line naming the file and the field (and `dfa diagnose` prints it as `dfa: error:`)."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from dfa_model import preset, simulate
from dfa_model.io.parameters import preset_text
from dfa_model.io.recordings import RecordingError, read_csv, read_dataset, read_hdf5, read_layout, read_tdms
from dfa_model.waveforms import Protocol

V, F = 6000.0, 5.0
LAB = {"time": "Time (s)", "voltage": "HV monitor", "force": "Load cell", "stroke": "Laser"}
MAPPING = "[columns]\n" + "".join(f'{c} = "{n}"\n' for c, n in LAB.items())
KV_MM = '[units]\nvoltage = "kV"\nstroke = "mm"\n'


@pytest.fixture(scope="module")
def sim():
    """A simulated recording (SI columns) at 1 kHz: 1 s square-wave reset, 4 s hold."""
    res = simulate(preset("vshape-table1"), Protocol.reset_then_hold(V, 4.0, reset=1.0), load=F,
                   t_eval=np.arange(0, 5.0005, 1e-3))
    return res


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "actuator.toml").write_text(preset_text("vshape-table1"))
    return tmp_path


def lab_csv(path, c, eol="\n"):
    """The recording as a lab export: its own column names, voltage in kV, stroke in mm."""
    lines = [f"# bench 2, {len(c['time'])} samples", ",".join(LAB.values())]
    lines += [f"{t:.10g},{v / 1e3:.10g},{f:.10g},{x * 1e3:.10g}"
              for t, v, f, x in zip(c["time"], c["voltage"], c["force"], c["stroke"])]
    path.write_bytes((eol.join(lines) + eol).encode())
    return path


def write_h5(path, c, group="run1", time=True, names=LAB, stroke_mm=True):
    h5py = pytest.importorskip("h5py")
    with h5py.File(path, "w") as f:
        g = f.require_group(group)
        for k in ("time", "voltage", "force", "stroke"):
            if k != "time" or time:
                g[names[k]] = c[k] * (1e3 if k == "stroke" and stroke_mm else 1.0)
        if not time:
            g.attrs["dt"] = 1e-3
    return path


def write_tdms(path, c, group="Analog", time=False, names=LAB, props=None):
    nptdms = pytest.importorskip("nptdms")
    wf = props or {"wf_increment": 1e-3, "wf_start_offset": 0.0}
    chans = [nptdms.ChannelObject(group, names[k], c[k] * (1e3 if k == "stroke" else 1.0), properties=wf)
             for k in ("time", "voltage", "force", "stroke") if k != "time" or time]
    with nptdms.TdmsWriter(path) as w:
        w.write_segment(chans)
    return path


def same_protocol(a, b):
    assert [s.label for s in a.stages] == [s.label for s in b.stages]
    for s, r in zip(a.stages, b.stages):
        assert s.duration == pytest.approx(r.duration, abs=1e-9)
        if hasattr(r.waveform, "times"):
            assert np.allclose(s.waveform.times, r.waveform.times, rtol=0, atol=1e-9)
            assert np.allclose(s.waveform.values, r.waveform.values, rtol=1e-9)
        else:
            assert s.waveform.V == pytest.approx(r.waveform.V, rel=1e-9)


def same_as(r, c, ref, rtol=1e-9):
    """r's arrays are the SI originals c; its protocol and load are the plain CSV's (ref)."""
    for k in ("time", "voltage", "force", "stroke"):
        got = {"time": r.t, "voltage": r.voltage, "force": r.force, "stroke": r.stroke}[k]
        assert np.allclose(got, c[k], rtol=rtol, atol=1e-15), k
    same_protocol(r.protocol, ref.protocol)
    assert r.load.F == pytest.approx(ref.load.F) and r.hold_voltage == pytest.approx(ref.hold_voltage)
    assert r.reset_end == pytest.approx(ref.reset_end, abs=1e-9)


@pytest.fixture
def ref(sim, tmp_path):
    sim.to_csv(tmp_path / "plain.csv")
    return read_csv(tmp_path / "plain.csv")


# ------------------------------------------------------------------------ round trips
def test_a_mapped_csv_in_kv_and_mm_reads_as_the_si_original(sim, ref, folder):
    c = sim.columns()
    (folder / "dataset.toml").write_text(MAPPING + KV_MM)
    r = read_csv(lab_csv(folder / "lab.csv", c), layout=read_layout(folder))
    same_as(r, c, ref)
    assert r.notes[0] == ("columns named in dataset.toml: time = 'Time (s)', voltage = 'HV monitor', "
                          "force = 'Load cell', stroke = 'Laser'")
    assert r.notes[1] == "dataset.toml [units]: voltage x 1000, stroke x 0.001 to SI"


def test_crlf_line_ends_read_as_lf(sim, ref, folder):
    c = sim.columns()
    (folder / "dataset.toml").write_text(MAPPING + KV_MM)
    lay = read_layout(folder)
    r = read_csv(lab_csv(folder / "crlf.csv", c, eol="\r\n"), layout=lay)
    assert b"\r\n" in (folder / "crlf.csv").read_bytes()
    same_as(r, c, ref)
    assert r.line[0] == 3            # line numbers count CRLF lines as lines (comment, header, first row)
    # CRLF with a byte-order mark and a units row (no dataset.toml)
    text = "\r\n".join(["time,voltage,force,stroke", "s,kV,N,mm"] +
                       [f"{t:.10g},{v / 1e3:.10g},{f:.10g},{x * 1e3:.10g}"
                        for t, v, f, x in zip(c["time"], c["voltage"], c["force"], c["stroke"])]) + "\r\n"
    (folder / "bom.csv").write_bytes(b"\xef\xbb\xbf" + text.encode())
    same_as(read_csv(folder / "bom.csv"), c, ref)


@pytest.mark.parametrize("time", [True, False], ids=["time-channel", "dt-attribute"])
def test_hdf5_reads_as_the_si_original(sim, ref, folder, time):
    c = sim.columns()
    (folder / "dataset.toml").write_text(MAPPING + '[units]\nstroke = "mm"\n[hdf5]\ngroup = "/run1"\n')
    r = read_hdf5(write_h5(folder / "a.h5", c, time=time), layout=read_layout(folder))
    same_as(r, c, ref)
    assert any("stroke x 0.001" in n for n in r.notes)
    assert time or any("time from the sample time 0.001 s (attribute dt of '/run1')" in n for n in r.notes)


@pytest.mark.parametrize("time", [False, True], ids=["wf_increment", "time-channel"])
def test_tdms_reads_as_the_si_original(sim, ref, folder, time):
    c = sim.columns()
    (folder / "dataset.toml").write_text(MAPPING + '[units]\nstroke = "mm"\n[tdms]\ngroup = "Analog"\n')
    r = read_tdms(write_tdms(folder / "a.tdms", c, time=time), layout=read_layout(folder))
    same_as(r, c, ref)
    assert time or any("time from the sample time 0.001 s (wf_increment of 'HV monitor')" in n for n in r.notes)


def test_a_dataset_of_mixed_formats_end_to_end(sim, folder):
    """dataset.toml maps the names and units of CSV, HDF5 and TDMS files in one folder;
    read_dataset reads all three as repetitions of one condition."""
    c = sim.columns()
    (folder / "dataset.toml").write_text(MAPPING + KV_MM + '[files]\ninclude = ["*.csv", "*.h5", "*.tdms"]\n'
                                         '[hdf5]\ngroup = "/run1"\n[tdms]\ngroup = "Analog"\n')
    lab_csv(folder / "r1.csv", c)
    c_kv = dict(c, voltage=c["voltage"] / 1e3)                # voltage in kV in every file ([units])
    write_h5(folder / "r2.h5", c_kv, time=False)
    write_tdms(folder / "r3.tdms", c_kv)
    (folder / "notes.txt").write_text("not a recording (not included)\n")
    d = read_dataset(folder)
    assert [r.path.name for r in d.recordings] == ["r1.csv", "r2.h5", "r3.tdms"]
    for r in d.recordings:
        same_as(r, c, d.recordings[0])
    assert list(d.conditions()) == [(V, F)] and len(d.conditions()[(V, F)]) == 3


def test_without_dataset_toml_only_csv_is_read(sim, folder):
    """No dataset.toml: today's contract exactly (*.csv); a binary file there is named
    when it is all there is."""
    c = sim.columns()
    write_h5(folder / "b.h5", c, group="/", names={k: k for k in LAB}, stroke_mm=False)
    with pytest.raises(RecordingError, match=r"no recordings \(\*\.csv\); expected one file per test \(b\.h5 is read "
                                             r"when the folder has a dataset\.toml\)$"):
        read_dataset(folder)
    sim.to_csv(folder / "a.csv")
    assert [r.path.name for r in read_dataset(folder).recordings] == ["a.csv"]
    (folder / "dataset.toml").write_text("")                   # an empty one: defaults, binary formats too
    assert [r.path.name for r in read_dataset(folder).recordings] == ["a.csv", "b.h5"]


# ------------------------------------------------------------------------ dataset.toml errors
@pytest.mark.parametrize("toml, pattern", [
    ("[colums]\nvoltage = 'V'\n", r"^dataset\.toml: unknown table \[colums\]; allowed tables: \[columns\], \[units\]"),
    ("units = 'kV'\n", r"^dataset\.toml: units = 'kV': a table \[units\] expected$"),
    ("scale = 2\n", r"^dataset\.toml: unknown key scale; allowed tables: \[columns\]"),
    ("[columns]\nvolts = 'HV'\n", r"^dataset\.toml: unknown key \[columns\] volts; allowed: time, voltage, force, "
                                  r"stroke, current$"),
    ("[columns]\nvoltage = 3\n", r"^dataset\.toml: \[columns\] voltage = 3: text expected$"),
    ("[columns]\nvoltage = 'A'\nforce = 'a'\n", r"^dataset\.toml: \[columns\] voltage and force both name 'a'; "
                                                r"expected one column of the file per name$"),
    ("[units]\nvoltage = 'kQ'\n", r"^dataset\.toml: \[units\] voltage = 'kQ': not a unit of voltage; allowed: v, kv$"),
    ("[units]\nspeed = 'm/s'\n", r"^dataset\.toml: unknown key \[units\] speed; allowed: time, voltage"),
    ("[files]\ninclude = '*.csv'\n", r"^dataset\.toml: \[files\] include = '\*\.csv': a list of patterns expected"),
    ("[files]\ninclude = ['../*.csv']\n", r"^dataset\.toml: \[files\] include has '\.\./\*\.csv': a file pattern "
                                          r"within the folder"),
    ("[files]\nmax_bytes = 1.5e9\n", r"^dataset\.toml: \[files\] max_bytes = 1500000000\.0: a positive whole number "
                                     r"of bytes expected$"),
    ("[files]\nexclude = ['a.csv']\n", r"^dataset\.toml: unknown key \[files\] exclude; allowed: include, max_bytes$"),
    ("[hdf5]\ndt = -1\n", r"^dataset\.toml: \[hdf5\] dt = -1: a positive number \(s\) expected$"),
    ("[tdms]\ndt = 0.001\n", r"^dataset\.toml: unknown key \[tdms\] dt; allowed: group$"),
    ("[columns\n", r"^dataset\.toml: not valid TOML: "),
])
def test_dataset_toml_errors_name_the_key(folder, toml, pattern):
    (folder / "dataset.toml").write_text(toml)
    with pytest.raises(RecordingError, match=pattern):
        read_dataset(folder)


def test_a_mapped_column_missing_from_a_file(sim, folder):
    (folder / "dataset.toml").write_text(MAPPING.replace("Laser", "LVDT"))
    lab_csv(folder / "a.csv", sim.columns())
    with pytest.raises(RecordingError, match=r"^a\.csv, row 2: \[columns\] stroke = 'LVDT' \(dataset\.toml\) is not "
                                             r"in the header 'Time \(s\),HV monitor,Load cell,Laser'; expected one of "
                                             r"its columns$"):
        read_dataset(folder)


def test_a_units_row_and_dataset_toml_disagreeing(sim, folder):
    c = sim.columns()
    (folder / "dataset.toml").write_text('[units]\nstroke = "um"\n')
    lines = ["time,voltage,force,stroke", "s,V,N,mm"] + [f"{t:.10g},{v:.10g},{f:.10g},{x * 1e3:.10g}" for t, v, f, x
                                                          in zip(c["time"], c["voltage"], c["force"], c["stroke"])]
    (folder / "a.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(RecordingError, match=r"^a\.csv, row 2: stroke in 'mm' \(units row\) but in 'um' "
                                             r"\(dataset\.toml \[units\] stroke\): they must agree$"):
        read_dataset(folder)
    (folder / "dataset.toml").write_text('[units]\nstroke = "MM"\n')          # agreeing: read, noted once
    r = read_dataset(folder).recordings[0]
    assert np.allclose(r.stroke, c["stroke"]) and [n for n in r.notes if "x 0.001" in n] == [
        "units row (line 2): stroke x 0.001 to SI"]


# ------------------------------------------------------------------------ limits and damaged files
def test_a_file_above_the_size_limit_is_refused_unread(sim, folder, monkeypatch):
    import dfa_model.io.recordings as recordings
    sim.to_csv(folder / "a.csv")
    n = (folder / "a.csv").stat().st_size
    (folder / "dataset.toml").write_text("[files]\nmax_bytes = 1000\n")
    with pytest.raises(RecordingError, match=rf"^a\.csv: \S+ KiB \({n} bytes\), above the limit of 1000 bytes "
                                             rf"\(1000 bytes, dataset\.toml \[files\] max_bytes\): refused unread$"):
        read_dataset(folder)
    (folder / "dataset.toml").write_text(f"[files]\nmax_bytes = {n}\n")
    assert len(read_dataset(folder).recordings) == 1
    monkeypatch.setattr(recordings, "MAX_BYTES", 2 ** 19)
    assert recordings.MAX_BYTES < n
    with pytest.raises(RecordingError, match=r"^a\.csv: .* above the limit of 512 KiB \(524288 bytes, MAX_BYTES; "
                                             r"dataset\.toml \[files\] max_bytes sets it\): refused unread$"):
        read_csv(folder / "a.csv")


def test_a_field_above_csvs_limit_is_one_line(tmp_path):
    rows = ["time,voltage,force,stroke"] + [f"{i * 1e-3:g},6000,5,0" for i in range(20)]
    rows[4] = "0.003,6000,5," + "1" * 140_000
    (tmp_path / "long.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(RecordingError, match=r"^long\.csv, row 5: a field longer than 131072 characters"):
        read_csv(tmp_path / "long.csv")
    (tmp_path / "head.csv").write_text("x" * 140_000 + "\n" + "\n".join(rows[1:]) + "\n")
    with pytest.raises(RecordingError, match=r"^head\.csv, row 1: a field longer than 131072 characters"):
        read_csv(tmp_path / "head.csv")
    # below csv's limit but no number: the message quotes it cut short
    rows[4] = "0.003,6000,5," + "x" * 100_000
    (tmp_path / "text.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(RecordingError, match=r"^text\.csv, row 5: stroke is 'x{40}\.\.\.', not a number$"):
        read_csv(tmp_path / "text.csv")


@pytest.mark.parametrize("suffix, module, extra", [(".h5", "h5py", "hdf5"), (".tdms", "nptdms", "tdms")])
def test_a_binary_file_without_its_library_names_the_extra(folder, monkeypatch, suffix, module, extra):
    monkeypatch.setitem(sys.modules, module, None)            # import fails as if not installed
    (folder / f"a{suffix}").write_bytes(b"\x00" * 64)
    (folder / "dataset.toml").write_text("")
    with pytest.raises(RecordingError, match=rf'^a\{suffix}: reading \S+ needs the optional {module} package: '
                                             rf'pip install "dfa-toolkit\[{extra}\]"$'):
        read_dataset(folder)


def test_hdf5_errors_name_the_field(sim, tmp_path):
    pytest.importorskip("h5py")
    from dfa_model.io.recordings import Layout
    c = sim.columns()
    (tmp_path / "junk.h5").write_bytes(b"not an HDF5 file\n" * 10)
    with pytest.raises(RecordingError, match=r"^junk\.h5: cannot read as HDF5: .*file signature not found"):
        read_hdf5(tmp_path / "junk.h5")
    plain = {k: k for k in LAB}
    write_h5(tmp_path / "a.h5", c, group="run1", names=plain, stroke_mm=False)
    with pytest.raises(RecordingError, match=r"^a\.h5: no group '/run2' \(\[hdf5\] group\); its groups: /, /run1$"):
        read_hdf5(tmp_path / "a.h5", layout=Layout(hdf5_group="/run2"))
    write_h5(tmp_path / "b.h5", c, group="/", time=False, names=plain, stroke_mm=False)
    import h5py
    with h5py.File(tmp_path / "b.h5", "a") as f:
        del f.attrs["dt"]
    with pytest.raises(RecordingError, match=r"^b\.h5: no time channel .* no sample time \(a dt or wf_increment "
                                             r"attribute, or dataset\.toml \[hdf5\] dt\)$"):
        read_hdf5(tmp_path / "b.h5")
    assert read_hdf5(tmp_path / "b.h5", layout=Layout(hdf5_dt=1e-3)).t[-1] == pytest.approx(5.0)
    with h5py.File(tmp_path / "b.h5", "a") as f:
        f["force"][7] = np.nan
        del f["stroke"]
        f["stroke"] = np.zeros((5, 2))
    with pytest.raises(RecordingError, match=r"^b\.h5: channel 'stroke' \(stroke\) has shape \(5, 2\); one 1-D"):
        read_hdf5(tmp_path / "b.h5", layout=Layout(hdf5_dt=1e-3))
    with h5py.File(tmp_path / "b.h5", "a") as f:
        del f["stroke"]
        f["stroke"] = c["stroke"][:-1]
    with pytest.raises(RecordingError, match=r"^b\.h5: channels of different lengths: voltage \('voltage'\) 5001, "
                                             r"force \('force'\) 5001, stroke \('stroke'\) 5000$"):
        read_hdf5(tmp_path / "b.h5", layout=Layout(hdf5_dt=1e-3))
    with h5py.File(tmp_path / "b.h5", "a") as f:
        del f["stroke"]
        f["stroke"] = c["stroke"]
    with pytest.raises(RecordingError, match=r"^b\.h5, sample 7: force is nan \(values must be finite numbers\)$"):
        read_hdf5(tmp_path / "b.h5", layout=Layout(hdf5_dt=1e-3))


def test_tdms_errors_name_the_field(sim, tmp_path):
    pytest.importorskip("nptdms")
    from dfa_model.io.recordings import Layout
    c = sim.columns()
    plain = {k: k for k in LAB}
    (tmp_path / "junk.tdms").write_bytes(b"not a TDMS file\n" * 10)
    with pytest.raises(RecordingError, match=r"^junk\.tdms: cannot read as TDMS: Segment does not start with"):
        read_tdms(tmp_path / "junk.tdms")
    (tmp_path / "empty.tdms").write_bytes(b"")
    with pytest.raises(RecordingError, match=r"^empty\.tdms: 0 groups \(none\): name the one with the channels in "
                                             r"dataset\.toml \[tdms\] group$"):
        read_tdms(tmp_path / "empty.tdms")
    write_tdms(tmp_path / "a.tdms", c, names=plain)
    with pytest.raises(RecordingError, match=r"^a\.tdms: no group 'Raw' \(\[tdms\] group\); its groups: Analog$"):
        read_tdms(tmp_path / "a.tdms", layout=Layout(tdms_group="Raw"))
    write_tdms(tmp_path / "b.tdms", c, names=plain, props={"unit_string": "V"})
    with pytest.raises(RecordingError, match=r"^b\.tdms: no time channel \('time'\) and no wf_increment property"):
        read_tdms(tmp_path / "b.tdms")
    with pytest.raises(RecordingError, match=r"^b\.tdms: \[columns\] force = 'Load cell' \(dataset\.toml\) is not in "
                                             r"the channels of group 'Analog' \(voltage, force, stroke\); expected one "
                                             r"of its columns$"):
        read_tdms(tmp_path / "b.tdms", layout=Layout(columns={"force": "Load cell"}))
    nptdms = pytest.importorskip("nptdms")
    chans = [nptdms.ChannelObject("Analog", k, c[k], properties={"wf_increment": dt})
             for k, dt in (("voltage", 1e-3), ("force", 1e-3), ("stroke", 2e-3))]
    with nptdms.TdmsWriter(tmp_path / "d.tdms") as w:
        w.write_segment(chans)
    with pytest.raises(RecordingError, match=r"^d\.tdms: the channels' sample times disagree: voltage wf_increment "
                                             r"0\.001 s, .*stroke wf_increment 0\.002 s"):
        read_tdms(tmp_path / "d.tdms")


def test_two_files_of_one_name_are_refused(sim, folder):
    c = sim.columns()
    sim.to_csv(folder / "a.csv")
    write_h5(folder / "a.h5", c, group="/", names={k: k for k in LAB}, stroke_mm=False)
    (folder / "dataset.toml").write_text("")
    with pytest.raises(RecordingError, match=r": a\.csv and a\.h5 are both recording 'a'; rename one$"):
        read_dataset(folder)


@pytest.mark.parametrize("toml, line", [
    ("[units]\nvoltage = 'kQ'\n", "dataset.toml: [units] voltage = 'kQ': not a unit of voltage; allowed: v, kv"),
    ("[files]\nmax_bytes = 100\n", "a.csv: "),
])
def test_dfa_diagnose_prints_a_reading_failure_as_one_line(sim, folder, capsys, toml, line):
    from dfa_model.cli import main
    sim.to_csv(folder / "a.csv")
    (folder / "dataset.toml").write_text(toml)
    assert main(["diagnose", str(folder), "--out", str(folder / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"dfa: error: {line}"), err
    assert not (folder / "out").exists()


def test_any_bytes_give_a_recording_or_one_line(tmp_path):
    """Damaged files (bytes cut, inserted, overwritten in a valid lab CSV, with a BOM, CRLF
    and a units row): read or a one-line RecordingError, never another exception."""
    hypothesis = pytest.importorskip("hypothesis")
    st = hypothesis.strategies
    t = np.arange(0, 0.2, 1e-3)
    v = np.where(t < 0.05, 6000.0, np.where(t < 0.1, -6000.0, 6000.0))
    good = ("\ufeff# lab\r\ntime;voltage;force;stroke\r\ns;kV;N;mm\r\n" + "".join(
        f"{a:g};{b / 1e3:g};5;{0.1 * a:g}\r\n" for a, b in zip(t, v))).encode()

    (tmp_path / "good.csv").write_bytes(good)
    assert read_csv(tmp_path / "good.csv").hold_voltage == pytest.approx(6000.0)

    @hypothesis.settings(max_examples=150, deadline=None, database=None)
    @hypothesis.given(st.lists(st.tuples(st.integers(0, len(good)), st.integers(0, 40), st.binary(max_size=20)),
                               min_size=1, max_size=4))
    def check(edits):
        data = bytearray(good)
        for at, cut, put in edits:
            data[at:at + cut] = put
        (tmp_path / "f.csv").write_bytes(bytes(data))
        try:
            read_csv(tmp_path / "f.csv")
        except RecordingError as exc:
            assert "\n" not in str(exc) and str(exc).startswith("f.csv")

    check()
