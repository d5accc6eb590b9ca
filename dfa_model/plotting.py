"""Plots of results (matplotlib, Agg backend: works without a display)."""
from __future__ import annotations

import numpy as np


def _plt():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def plot_result(res, path=None, title=None):
    plt = _plt()
    fig, ax = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    ax[0].plot(res.t, res.x * 1e3, lw=1.2)
    ax[0].set_ylabel("stroke x (mm)")
    ax[1].plot(res.t, res.V / 1e3, lw=0.8, color="C3")
    ax[1].set_ylabel("voltage (kV)")
    ax[2].plot(res.t, res.Fe, lw=0.8, color="C2", label="electrostatic (zipping)")
    ax[2].plot(res.t, res.F, lw=0.8, color="k", ls="--", label="load")
    ax[2].set_ylabel("force (N)")
    ax[2].set_xlabel("time (s)")
    ax[2].legend(loc="best", fontsize=8)
    for span_label, color in (("reset", "0.9"),):
        span = res.stage(span_label)
        if span:
            for a in ax:
                a.axvspan(*span, color=color, zorder=0)
    p = res.params
    ax[0].set_title(title or f"{p.layout}, {np.max(np.abs(res.V)) / 1e3:g} kV, "
                    f"unzipping speed {res.unzipping_speed * 1e6:.2f} um/s")
    for a in ax:
        a.grid(alpha=0.3)
    fig.tight_layout()
    if path is not None:
        from .fileio import write_atomic
        try:
            write_atomic(path, lambda tmp: fig.savefig(tmp, dpi=120))
        finally:
            plt.close(fig)
        return None
    return fig
