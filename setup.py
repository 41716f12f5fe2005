"""Build the C engine into the package (gyrosim.core._engine); the metadata is in pyproject.toml.

The engine (src/gyrosim/core/engine/) is compiled with the flags in engine/cflags.txt, the same flags the FMU
builder uses, so Model.step and every FMU give the same bits. OpenMP is used for the many-body loop when the
compiler has it (the bits do not depend on the thread count).
"""

import os
import shutil
import subprocess
import tempfile
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

HERE = Path(__file__).parent
ENGINE = Path("src/gyrosim/core/engine")
CFLAGS = (HERE / ENGINE / "cflags.txt").read_text().split()
#: engine.c's parts: headers it alone includes (one translation unit, so that the hot code inlines)
ENGINE_PARTS = ("body_dynamics.h", "angles.h", "monitor.h", "splitting.h", "outputs.h", "exact_steps.h", "block.h")


def _has_openmp(compiler_cmd) -> bool:
    if os.environ.get("GYROSIM_NO_OPENMP"):
        return False
    cc = shutil.which(compiler_cmd[0]) if compiler_cmd else None
    if not cc:
        return False
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / "t.c"
        src.write_text("#include <omp.h>\nint main(void) { return omp_get_max_threads() > 0 ? 0 : 1; }\n")
        r = subprocess.run([*compiler_cmd, "-fopenmp", str(src), "-o", str(Path(tmp) / "t")],
                           capture_output=True)
        return r.returncode == 0


class BuildExt(build_ext):
    def build_extensions(self):
        cc = getattr(self.compiler, "compiler_so", None) or ["cc"]
        if _has_openmp(cc[:1]):
            for ext in self.extensions:
                ext.extra_compile_args.append("-fopenmp")
                ext.extra_link_args.append("-fopenmp")
        super().build_extensions()


setup(
    ext_modules=[
        Extension(
            "gyrosim.core._engine",
            sources=["src/gyrosim/core/_enginemodule.c", str(ENGINE / "engine.c"), str(ENGINE / "exact.c"),
                     str(ENGINE / "rk.c"), str(ENGINE / "tree.c"),
                     str(ENGINE / "tree_cs.c")],
            depends=[str(ENGINE / "gyrosim_engine.h"), str(ENGINE / "gyrosim_ode.h"), str(ENGINE / "gyrosim_tree.h"),
                     str(ENGINE / "rk_tables.h"), str(ENGINE / "rk_driver.h"), str(ENGINE / "exact_fast.h"),
                     *(str(ENGINE / h) for h in ENGINE_PARTS),
                     str(ENGINE / "cflags.txt"), str(ENGINE / "tree.c")],
            extra_compile_args=list(CFLAGS),
            libraries=["m"],
        )
    ],
    cmdclass={"build_ext": BuildExt},
)
