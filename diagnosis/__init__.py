"""diagnosis: fit recordings, locate where model and measurement disagree, name and model
the missing physics.

    from dfa_model.io.recordings import read_dataset
    import diagnosis
    D = diagnosis.diagnose(read_dataset("my_dataset/"))
    diagnosis.write_report(D, "out/")        # report.json, report.md, plots
    D.missing_physics, D.final.values

    dfa diagnose my_dataset/ --out out/
"""
from .catalog import CATALOG_IDS, NOMINAL, PHYSICS, Entry
from .diagnose import Diagnosis, diagnose
from .fit import FitError, FitResult, fit
from .locate import locate
from .report import write as write_report

__all__ = ["CATALOG_IDS", "NOMINAL", "PHYSICS", "Entry", "Diagnosis", "diagnose", "FitError", "FitResult", "fit",
           "locate", "write_report"]
