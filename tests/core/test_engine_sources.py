"""Every file the engine's C units include is one that the builds carry: the extension (setup.py compiles every
``.c`` of core/engine/ and rebuilds when any ``.h`` there changes) and every FMU (an FMU's sources compile on their
own, so they hold every unit and every file a unit includes), with nothing outside the engine's folder."""

import re
from pathlib import Path

from gyrosim.fmu import build

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"


def _included(name: str, seen: set[str]) -> set[str]:
    """The files that ``name`` includes by a quoted name, directly or through another (system headers aside)."""
    for inc in re.findall(r'^\s*#\s*include\s+"([^"]+)"', (ENGINE / name).read_text(), re.M):
        if inc not in seen:
            seen.add(inc)
            assert (ENGINE / inc).is_file(), f"{name} includes {inc!r}, which is not in core/engine/"
            _included(inc, seen)
    return seen


def test_every_included_file_is_carried():
    units = sorted(p.name for p in ENGINE.glob("*.c"))
    assert list(build.ENGINE_UNITS) == units
    included = set().union(*(_included(u, set()) for u in units)) - set(units) - {"tree.c"}
    assert {"gyrosim_engine.h", "rk_driver.h", "body_dynamics.h"} <= included
    assert included <= set(build.ENGINE_HEADERS)
    carried = build.engine_sources()
    for name in (*units, *included, "cflags.txt"):
        assert carried[name] == (ENGINE / name).read_text(), name
