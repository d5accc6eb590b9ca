"""Output files get the mode of any new file under the user's umask (0o644 under 0o022,
0o600 under 0o077), still written atomically (dfa_model.io.fileio.write_atomic): the CSV and
plot of `dfa simulate`, an FMU and an SSP of `dfa fmu build` (and the entries inside
them), and a diagnosis's report, improved model, plots and protocol files."""
from __future__ import annotations

import contextlib
import os
import stat
import zipfile

import pytest

from dfa_model import preset
from dfa_model.cli import main
from dfa_model.io.fileio import write_text_atomic

MODES = [(0o022, 0o644), (0o077, 0o600)]


@contextlib.contextmanager
def umask(mask):
    old = os.umask(mask)
    try:
        yield
    finally:
        os.umask(old)


def mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


def no_leftovers(folder):
    assert [p.name for p in folder.iterdir() if ".part" in p.name or p.name.endswith(".probe")] == []


@pytest.mark.parametrize("mask, want", MODES)
def test_write_atomic_uses_the_umask_and_leaves_it(tmp_path, mask, want):
    target = tmp_path / "out.txt"
    target.write_text("old")
    os.chmod(target, 0o600 if want != 0o600 else 0o644)     # an existing file of another mode is replaced
    with umask(mask):
        write_text_atomic(target, "new")
        assert os.umask(mask) == mask                       # the process umask is never touched
    assert target.read_text() == "new" and mode(target) == want
    no_leftovers(tmp_path)


@pytest.mark.parametrize("mask, want", MODES)
def test_simulate_csv_and_plot(tmp_path, capsys, mask, want):
    csv, png = tmp_path / "run.csv", tmp_path / "run.png"
    with umask(mask):
        rc = main(["simulate", "--preset", "vshape-table1", "--set", "N=21", "--voltage", "6000", "--force", "5",
                   "--duration", "0.2", "--out", str(csv), "--plot", str(png)])
    assert rc == 0, capsys.readouterr().err
    assert mode(csv) == want and mode(png) == want
    no_leftovers(tmp_path)


def _zip_modes(path) -> dict:
    with zipfile.ZipFile(path) as z:
        return {i.filename: stat.S_IMODE(i.external_attr >> 16) for i in z.infolist()}


@pytest.mark.parametrize("mask, want", MODES)
def test_fmu_and_ssp(tmp_path, capsys, mask, want):
    pytest.importorskip("pythonfmu")
    pytest.importorskip("fmpy")
    fmu, ssp = tmp_path / "a.fmu", tmp_path / "a.ssp"
    with umask(mask):
        assert main(["fmu", "build", "--out", str(fmu)]) == 0, capsys.readouterr().err
        assert main(["fmu", "build", "--system", "--out", str(ssp)]) == 0, capsys.readouterr().err
    assert mode(fmu) == want and mode(ssp) == want
    no_leftovers(tmp_path)
    # inside: what an unpacking tool that keeps modes (unzip) creates; binaries also executable
    entries = _zip_modes(fmu)
    assert entries["modelDescription.xml"] == want and entries["resources/dfa_params.toml"] == want
    so = {k: v for k, v in entries.items() if k.startswith("binaries/") and k.endswith(".so")}
    assert so and set(so.values()) == {want | (want & 0o444) >> 2}
    assert set(v for k, v in entries.items() if k not in so) == {want}
    assert set(_zip_modes(ssp).values()) == {want}
    with zipfile.ZipFile(ssp) as z:
        z.extract("resources/DriveElectronics.fmu", tmp_path / "x")
    assert set(v for k, v in _zip_modes(tmp_path / "x" / "resources" / "DriveElectronics.fmu").items()
               if not k.endswith(".so")) == {want}


@pytest.fixture(scope="module")
def small_diagnosis(tmp_path_factory):
    """One short recording, the baseline fit only (no candidates): what matters is the writing."""
    import diagnosis
    from dfa_model.io.recordings import read_dataset
    from dfa_model.io.synthetic import generate_dataset
    from diagnosis.fit import InProcess
    folder = tmp_path_factory.mktemp("modes_diag")
    nominal = preset("vshape-table1").replace(N=21, rho_l=3e12)
    generate_dataset(folder / "data", nominal.replace(rho_l=2e12), nominal, [(6000.0, 5.0)], repetitions=1,
                     reset=0.5, hold=1.5, seed=5)
    return diagnosis.diagnose(read_dataset(folder / "data"), executor=InProcess(), candidates=[])


@pytest.mark.parametrize("mask, want", MODES)
def test_diagnosis_report(small_diagnosis, tmp_path, mask, want):
    import diagnosis
    out = tmp_path / "out"
    with umask(mask):
        report = diagnosis.write_report(small_diagnosis, out)
    files = [out / n for n in ("report.json", "report.md", report["improved_params"], "residuals.png",
                               "overlays.png")] + [out / p for p in report["protocols"].values()]
    assert {f.name: mode(f) for f in files} == {f.name: want for f in files}
    no_leftovers(out)
