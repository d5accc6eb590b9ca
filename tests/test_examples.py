"""Smoke test: every figure example runs on its reduced grid (--quick) through the one
command that regenerates them (examples/make_figures.py), and writes a non-trivial PNG."""
import subprocess
import sys
from pathlib import Path

from PIL import Image

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"


def test_every_figure_example_runs_quick(tmp_path):
    sys.path.insert(0, str(EXAMPLES))
    try:
        import make_figures
    finally:
        sys.path.pop(0)
    proc = subprocess.run([sys.executable, str(EXAMPLES / "make_figures.py"), "--quick", "--out", str(tmp_path)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stdout[-4000:] + proc.stderr[-2000:]
    for name, (_, pngs) in make_figures.EXAMPLES.items():
        assert f"ok  {name}" in proc.stdout, proc.stdout
        for png in pngs:                  # a real figure: decodes, full size, more than a few colours drawn
            with Image.open(tmp_path / png) as im:
                im.load()
                colours = im.convert("RGB").getcolors(maxcolors=1 << 16)
                assert im.format == "PNG" and min(im.size) >= 400 and len(colours) > 16, (png, im.size)
