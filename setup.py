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
            # the whole engine folder (one engine; the FMU builder copies the same files into every FMU)
            sources=["src/gyrosim/core/_enginemodule.c", *sorted(str(f) for f in ENGINE.glob("*.c"))],
            depends=[*sorted(str(f) for f in ENGINE.glob("*.h")), str(ENGINE / "cflags.txt")],
            extra_compile_args=list(CFLAGS),
            libraries=["m"],
        )
    ],
    cmdclass={"build_ext": BuildExt},
)
