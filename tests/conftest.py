"""Shared test settings (hypothesis kept small for a 2-core CI) and the C FMI host fixture."""

import os
import subprocess
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

settings.register_profile("ci", max_examples=60, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "ci"))

#: A C FMI 2.0 / 3.0 host that runs a script of FMI calls (no Python in its process)
HOST_SOURCE = Path(__file__).parent / "standalone" / "host" / "fmi_host.c"


@pytest.fixture(scope="session")
def host(tmp_path_factory):
    """``host(fmu, script) -> stdout`` runs the C host (compiled once; no Python in its process) on the binary
    of ``fmu`` (anything with ``version``, ``binary`` and ``token``); see tests/standalone/host/fmi_host.c."""
    from gyrosim.fmu.build import fmi_include_dir

    exe = tmp_path_factory.mktemp("host") / "fmi_host"
    # no -lm: the FMU's binary must bring its own libm dependency
    r = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", f"-I{fmi_include_dir()}", str(HOST_SOURCE),
                        "-ldl", "-o", str(exe)], capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr, r.stderr

    def _run(fmu, script: str, check: bool = True) -> str:
        p = subprocess.run([str(exe), str(fmu.version), str(fmu.binary), fmu.token], input=script,
                           capture_output=True, text=True, timeout=120)
        if check:
            assert p.returncode == 0, p.stdout[-3000:] + p.stderr
            assert "DONE" in p.stdout
        return p.stdout

    _run.exe = exe
    return _run
