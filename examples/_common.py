"""Shared helpers for the example scripts: output folder and a quiet matplotlib."""
import os
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dfa_model import PhysicsWarning  # noqa: E402

warnings.simplefilter("ignore", PhysicsWarning)
OUT = os.environ.get("DFA_EXAMPLES_OUT", os.path.join(os.path.dirname(__file__), "figures"))
os.makedirs(OUT, exist_ok=True)


def save(fig, name):
    path = os.path.join(OUT, name)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print("wrote", path)
    return path
