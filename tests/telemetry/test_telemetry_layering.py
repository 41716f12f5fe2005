"""Formats know no transport: telemetry/ imports nothing from service/ and no zenoh; every Zenoh loop is in
service/; one module maps keys to topics."""

import ast
import subprocess
import sys
from pathlib import Path

import gyrosim

PKG = Path(gyrosim.__file__).resolve().parent


def _imports(path: Path) -> set[str]:
    tree = ast.parse(path.read_text())
    out = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = ("." * node.level) + (node.module or "")
            out.add(base)
    return out


def test_telemetry_imports_neither_service_nor_zenoh():
    for f in sorted((PKG / "telemetry").glob("*.py")):
        for name in _imports(f):
            assert not name.startswith(("..service", "gyrosim.service", "zenoh")), (f.name, name)
        assert "zenoh.open" not in f.read_text() and "declare_publisher" not in f.read_text(), f.name


def test_importing_every_telemetry_module_loads_no_service_and_no_zenoh():
    mods = [f"gyrosim.telemetry.{f.stem}" for f in (PKG / "telemetry").glob("*.py") if f.stem != "__init__"]
    code = ("import importlib, sys\n"
            f"for m in {mods!r}: importlib.import_module(m)\n"
            "print(sorted(m for m in sys.modules if m.startswith(('gyrosim.service', 'zenoh'))))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120,
                         env={"PYTHONPATH": str(PKG.parent), "PATH": "/usr/bin:/bin"})
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_the_zenoh_loops_live_in_service_and_one_module_maps_keys_to_topics():
    assert not (PKG / "telemetry" / "replay.py").exists()
    for loop in ("serve", "record", "replay"):
        assert "zenoh" in (PKG / "service" / f"{loop}.py").read_text()
    defs = [f for f in PKG.rglob("*.py") if any(f"def {fn}" in f.read_text() for fn in ("topic_for_key",
                                                                                             "key_for_topic"))]
    assert [f.relative_to(PKG).as_posix() for f in defs] == ["telemetry/topics.py"]
    from gyrosim.service import keys
    from gyrosim.telemetry import topics

    assert keys.topic_for_key is topics.topic_for_key and keys.key_for_topic is topics.key_for_topic
