"""Every file the engine's C units include is one that the builds carry: setup.py's ``depends`` (a change rebuilds
the extension) and the FMUs' engine files (an FMU's sources compile on their own)."""

import re
from pathlib import Path

from gyrosim.fmu import build, tree_fmu

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
SETUP = (Path(__file__).resolve().parents[2] / "setup.py").read_text()


def _included(name: str, seen: set[str]) -> set[str]:
    """The engine's files that ``name`` includes, directly or through another."""
    for inc in re.findall(r'^\s*#\s*include\s+"([^"]+)"', (ENGINE / name).read_text(), re.M):
        if (ENGINE / inc).is_file() and inc not in seen:
            seen.add(inc)
            _included(inc, seen)
    return seen


def test_every_included_file_is_carried():
    units = list(build.ENGINE_UNITS)
    included = set().union(*(_included(u, set()) for u in units)) - set(units) - {"tree.c"}
    assert included, "the units include the engine's headers"
    assert included <= set(build._ENGINE) - set(units)
    assert included <= set(tree_fmu.TREE_ENGINE)
    assert included <= set(build.ENGINE_HEADERS)
    for name in included:
        assert f'"{name}"' in SETUP, f"setup.py's depends lacks {name}"
