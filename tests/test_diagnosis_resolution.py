"""The diagnosis rules out its own discretization before naming missing physics
(diagnosis.diagnose._resolution_check). Data from the paper's model at N = 81, fitted at
N = 21 with 0.5 um noise: the coarse model's error against the finer truth is 5x the
noise, and a polarization branch takes up half of it - but its gain falls from 50 % to
13 % when the elements double, so it is not named. Small and in this process (~10 s)."""
from __future__ import annotations

import json

import pytest

import diagnosis
from dfa_model import parameters, preset
from dfa_model.recordings import read_dataset
from dfa_model.synthetic import Measurement, generate_dataset


class InProcess:
    def map(self, fn, jobs):
        return map(fn, jobs)

    def shutdown(self):
        pass


@pytest.fixture(scope="module")
def coarse(tmp_path_factory):
    folder = tmp_path_factory.mktemp("resolution")
    nominal = preset("vshape-table1").replace(N=21, rho_l=3e12)
    generate_dataset(folder / "data", nominal.replace(N=81, rho_l=2e12), nominal,
                     [(5000.0, 5.0), (6000.0, 5.0), (7000.0, 5.0)], repetitions=2, reset=0.5, hold=5.0, seed=3,
                     measurement=Measurement(noise=0.5e-6, quantum=0.1e-6))
    forms = [e for e in diagnosis.PHYSICS if e.name == "polarization_branch"]
    D = diagnosis.diagnose(read_dataset(folder / "data"), executor=InProcess(), candidates=forms)
    return D, diagnosis.write_report(D, folder / "out"), folder / "out"


def test_an_entry_that_only_absorbs_resolution_error_is_not_named(coarse):
    D, report, out = coarse
    r = report["resolution"]
    assert [e.key for e in D.chain] == ["polarization_branch"]        # the rounds kept it at N = 21
    assert r["resolution_only"] and r["dropped"] == ["polarization_branch"], r
    assert r["gain"] > 0.3 and r["gain_fine"] < 0.5 * r["gain"]
    assert report["missing_physics"] == [] and "only took up the model's discretization error" in \
        report["conclusion"]
    # the final model is the baseline at the finer N, and improved.toml says why
    assert D.final.params.N == 41 and report["fit"]["improved"] is not None
    assert parameters.load(out / "improved.toml").N == 41
    assert "N raised from 21 to 41" in (out / "improved.toml").read_text()
    assert json.loads((out / "report.json").read_text())["resolution"]["N_fine"] == 41
