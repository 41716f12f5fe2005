"""Shared fixtures: the FMUs are built once per test session (in a temporary folder) and reused."""

from __future__ import annotations

from pathlib import Path

import pytest

from fmi_slave import FmiSlave

pytest.importorskip("fmpy")

SCENES = (None, "heavy_top", "free_body", "gyroscope")


@pytest.fixture(scope="session")
def fmu_dir(tmp_path_factory):
    return tmp_path_factory.mktemp("fmus")


@pytest.fixture(scope="session")
def build(fmu_dir):
    """``build(scene, fmi_version) -> Path``, cached for the session."""
    from gyrosim.fmu import build_fmu

    cache = {}

    def _build(scene=None, fmi_version=2):
        key = (scene, fmi_version)
        if key not in cache:
            cache[key] = build_fmu(scene, fmi_version, fmu_dir / f"fmi{fmi_version}")
        return cache[key]

    return _build


class Slave(FmiSlave):
    """:class:`FmiSlave` of a built FMU, with its model description (``md``)."""

    def __init__(self, path, unzip_dir, name="instance", logging_on=False):
        from fmpy import read_model_description

        self.md = read_model_description(str(path))
        super().__init__(int(self.md.fmiVersion[0]), unzip_dir, self.md.coSimulation.modelIdentifier, self.md.guid,
                         {v.name: v.valueReference for v in self.md.modelVariables}, name, logging_on)

    def outputs(self):
        names = [v.name for v in self.md.modelVariables if v.causality == "output" and not v.dimensions]   # scalars
        return dict(zip(names, self.get(*names)))


@pytest.fixture(scope="session")
def unzipped(build, tmp_path_factory):
    """``unzipped(scene, fmi_version) -> Path`` of the extracted FMU (extracted once per session)."""
    from fmpy import extract

    cache = {}

    def _unzip(scene=None, fmi_version=2):
        key = (scene, fmi_version)
        if key not in cache:
            path = build(scene, fmi_version)
            cache[key] = (path, Path(extract(str(path), str(tmp_path_factory.mktemp("unzip")))))
        return cache[key]

    return _unzip


@pytest.fixture
def slave(unzipped):
    """``slave(scene, fmi_version, name=...) -> Slave``; every instance is freed after the test."""
    made = []

    def _make(scene=None, fmi_version=2, **kw):
        path, d = unzipped(scene, fmi_version)
        s = Slave(path, d, **kw)
        made.append(s)
        return s

    yield _make
    for s in made:
        if not s.freed:
            s.freed = True
            s.fmu.freeInstance()
