"""The wheel's build step that compiles bitemesh's numba kernels into it (the rest of the build: pyproject.toml).

A first run compiles about 170 kernels before it meshes (25-40 s on 2 cores).  numba keys its cache by the source
file's content (not its date), numba's version and the CPU, so the cache written into the build tree is used where
the wheel is installed on the machine that built it (``pip install .``) with the same numba, and ignored elsewhere
(there the kernels compile on first use, as without it).  An editable install compiles on first use.
"""
import os
import subprocess
import sys
from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

COMPILE = "from bitemesh.meshing import compile_kernels; compile_kernels()"


class BuildWithKernels(build_py):
    """build_py, then the kernels compiled into the built package's ``__pycache__`` folders."""

    def run(self):
        super().run()
        if self.editable_mode:
            return
        for stale in (*Path(self.build_lib).rglob("*.nbi"), *Path(self.build_lib).rglob("*.nbc")):
            stale.unlink()   # an earlier build's, some of code since changed
        environment = {name: value for name, value in os.environ.items()
                       if not name.startswith(("NUMBA_", "BITEMESH_"))}   # the cache in the tree, every kernel
        environment["PYTHONPATH"] = os.pathsep.join(filter(None, [os.path.abspath(self.build_lib),
                                                                  environment.get("PYTHONPATH")]))
        run = subprocess.run([sys.executable, "-c", COMPILE], env=environment, cwd=self.build_lib,
                             capture_output=True, text=True)
        if run.returncode:   # the wheel without the cache: the kernels compile on first use
            self.warn(f"bitemesh's kernels not compiled into the wheel: {run.stderr.strip().splitlines()[-1:]}")


setup(cmdclass={"build_py": BuildWithKernels})
