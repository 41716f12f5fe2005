"""Fixtures of the standalone-FMU tests: FMUs and the C host built once per session (in a temporary folder)."""

from __future__ import annotations

import shutil
import zipfile

import pytest

pytest.importorskip("fmpy")
if shutil.which("gcc") is None:  # pragma: no cover
    pytest.skip("the standalone FMU needs gcc", allow_module_level=True)

from standalone_helpers import BuiltFMU  # noqa: E402


@pytest.fixture(scope="session")
def standalone(tmp_path_factory):
    """``standalone(scene, fmi_version) -> BuiltFMU``, built and extracted once per session."""
    from fmpy import read_model_description

    from gyrosim.fmu import build_fmu as build_standalone

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
