"""Fixtures of the standalone-FMU tests: FMUs and the C host built once per session (in a temporary folder)."""

from __future__ import annotations

import shutil
import subprocess
import zipfile

import pytest

pytest.importorskip("fmpy")
if shutil.which("gcc") is None:  # pragma: no cover
    pytest.skip("the standalone FMU needs gcc", allow_module_level=True)

from standalone_helpers import HOST_SOURCE, BuiltFMU  # noqa: E402


@pytest.fixture(scope="session")
def standalone(tmp_path_factory):
    """``standalone(scene, fmi_version) -> BuiltFMU``, built and extracted once per session."""
    from fmpy import read_model_description

    from gyrosim.fmu.standalone import build_standalone

    root = tmp_path_factory.mktemp("standalone")
    cache = {}

    def _get(scene=None, fmi_version=2):
        key = (scene, fmi_version)
        if key not in cache:
            path = build_standalone(scene, fmi_version, root / f"fmi{fmi_version}")
            d = root / f"unzip-{path.stem}-{fmi_version}"
            with zipfile.ZipFile(path) as zf:
                zf.extractall(d)
            md = read_model_description(str(path))
            token = md.guid if fmi_version == 2 else md.instantiationToken
            cache[key] = BuiltFMU(path, d, fmi_version, md.coSimulation.modelIdentifier, token,
                                  {v.name: v.valueReference for v in md.modelVariables})
        return cache[key]

    return _get


@pytest.fixture(scope="session")
def host(tmp_path_factory):
    """``host(fmu, script) -> stdout`` runs the C host (compiled once) on the FMU's binary."""
    from gyrosim.fmu.standalone.build import fmi_include_dir

    exe = tmp_path_factory.mktemp("host") / "fmi_host"
    # no -lm: the FMU's binary must bring its own libm dependency
    r = subprocess.run(["gcc", "-std=c99", "-O2", "-Wall", "-Wextra", f"-I{fmi_include_dir()}", str(HOST_SOURCE),
                        "-ldl", "-o", str(exe)], capture_output=True, text=True)
    assert r.returncode == 0 and not r.stderr, r.stderr

    def _run(fmu: BuiltFMU, script: str, check: bool = True) -> str:
        p = subprocess.run([str(exe), str(fmu.version), str(fmu.binary), fmu.token], input=script,
                           capture_output=True, text=True, timeout=120)
        if check:
            assert p.returncode == 0, p.stdout[-3000:] + p.stderr
            assert "DONE" in p.stdout
        return p.stdout

    _run.exe = exe
    return _run
