"""Build hook: compile the solver's kernels ahead of time (dfa_model/aot.py) when the
package is built or installed, so that the first `dfa simulate` compiles nothing.

Everything else is in pyproject.toml. If the compilation fails (no C compiler, numba
without its AOT compiler), the package is installed without the extension and compiles
its kernels with numba on first use instead (dfa_model/_jit.py); the build says so.
"""
import os
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).resolve().parent
AOT = "dfa_model._kernels_aot"


class BuildKernels(build_ext):
    def build_extension(self, ext):
        if ext.name != AOT:
            return super().build_extension(ext)
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        # DFA_JIT: the builder never loads an installed build of the same sources (an editable
        # install beside it) - it compiles these sources, whatever else is on the path
        env = dict(os.environ, DFA_JIT="1",
                   PYTHONPATH=os.pathsep.join([str(HERE), os.environ.get("PYTHONPATH", "")]))
        r = subprocess.run([sys.executable, "-m", "dfa_model.aot", "--out", str(target.parent)], cwd=HERE, env=env,
                           capture_output=True, text=True)
        if r.returncode != 0 or not target.exists():
            tail = (r.stdout + r.stderr).strip().splitlines()[-5:]
            print("dfa_model: WARNING: could not compile the kernels ahead of time; they will be compiled by numba "
                  "on first use (about 30 s, cached). " + " | ".join(tail), file=sys.stderr)
        else:
            print(r.stdout.strip())

    def get_source_files(self):
        return []


# the extension's sources are Python (compiled by numba.pycc), so no C sources here
setup(ext_modules=[Extension(AOT, sources=[], optional=True)], cmdclass={"build_ext": BuildKernels})
