"""Shared helpers for the example scripts: output folder, quick mode, a quiet matplotlib,
the paper's rho_l band.

Every example takes `--quick` (or DFA_EXAMPLES_QUICK=1): a reduced grid that runs in
seconds, for the smoke test (tests/test_examples.py). Its numbers are not the README's.
"""
import os
import sys
import warnings

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

from dfa_model import PhysicsWarning  # noqa: E402

warnings.simplefilter("ignore", PhysicsWarning)
QUICK = "--quick" in sys.argv[1:] or os.environ.get("DFA_EXAMPLES_QUICK", "") not in ("", "0")
OUT = os.environ.get("DFA_EXAMPLES_OUT", os.path.join(os.path.dirname(os.path.abspath(__file__)), "figures"))
os.makedirs(OUT, exist_ok=True)



def style():
    """The paper-figure examples' look (opt-in: the other examples keep matplotlib's)."""
    plt.rcParams.update({"font.size": 9, "axes.titlesize": 9.5, "legend.fontsize": 8, "axes.grid": True,
                         "grid.alpha": 0.3, "legend.framealpha": 0.9})


# the paper's liquid resistivity band (Sec. 4.3: 2.5e12 ohm m best fit, 2e12 and 3e12 bounds;
# Table 1 and Sec. 3 use 2e12)
RHO_BAND = (2e12, 2.5e12, 3e12)


def rho_label(rho):
    m, e = f"{rho:.1e}".split("e")
    return rf"$\rho_l$ = {m}$\times10^{{{int(e)}}}$ Ω m"


def rho_band(ax, x, ys, color, highlight, marker="o", ms=3):
    """The three rho_l curves ys[rho] over x: the band between the bounds shaded, the
    highlighted one bold and solid, the others thin with their own dash so that every
    legend entry is distinct."""
    lo, hi = min(ys), max(ys)
    ax.fill_between(x, ys[lo], ys[hi], color=color, alpha=0.15, lw=0)
    dashes = {lo: (0, (1.5, 1.5)), hi: (0, (5, 2))}
    for rho in sorted(ys):
        bold = rho == highlight
        ax.plot(x, ys[rho], color=color, lw=2.0 if bold else 1.0, alpha=1.0 if bold else 0.8,
                ls="-" if bold else dashes.get(rho, (0, (3, 1, 1, 1))), marker=marker, ms=ms if bold else 0,
                label=rho_label(rho) + (" (bold)" if bold else ""))


def compact_png(path, colors=128):
    """Rewrite a PNG with a 128-colour palette: line plots look the same at a third of the
    size (the committed figures stay a few hundred kB in all)."""
    from PIL import Image        # matplotlib's own dependency
    with Image.open(path) as im:
        q = im.convert("RGB").quantize(colors=colors, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    q.save(path, optimize=True)


def save(fig, name, tight=True, out=None):
    path = os.path.join(out or OUT, name)
    if tight:
        fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    compact_png(path)
    print("wrote", path)
    return path
