"""Build the gyrosim FMU: FMI 2.0 / 3.0 co-simulation and model exchange, native code from the engine's C sources.

One FMU kind, offering co-simulation, model exchange or both (``fmi_type``; both interfaces in one binary, as the
Modelica Reference FMUs do). Its binary is the C engine (``core/engine/``: the same sources and floating-point flags
as the Python extension, so an FMU run and ``Model.step`` agree to the bit) plus the FMI glue in ``c/`` (variables,
validation, time, saved state; no physics). No Python on the host. The FMU carries its sources (FMI 2.0
``SourceFiles``, FMI 3.0 ``sources/buildDescription.xml``), from which it rebuilds to the same bits.

Every scene builds the same way: the binary is every engine source (one engine) and one glue,
``c/gyrosim_model.c``, which knows no scene. What is particular to the scene is data in the generated
``gyrosim_config.h``: its engine system (``gyrosim_system.h``: the description ``gs_sys_init`` takes, the row sizes,
the start rows) and a table from value reference to what the variable is, both from :mod:`gyrosim.fmu.layout`. The
variables are :meth:`Scene.variables <gyrosim.scene.Scene.variables>` in that order from value reference 1 (FMI 3.0:
``time`` at 0); a multi-body scene names them ``<body>.<name>`` (``fast.q_w``). Model exchange adds local variables
after all the others (the value references of the co-simulation variables do not change): a work integral's balance
where it is a continuous state (``energy_expected``) and the derivative ``der(<state>)`` of every continuous state
(:func:`gyrosim.fmu.layout.me_rows`).
"""

from __future__ import annotations

import contextlib
import hashlib
import math
import os
import re
import shutil
import subprocess
import tempfile
import threading
import uuid
import xml.etree.ElementTree as ET
import zipfile
from importlib import resources
from pathlib import Path

import numpy as np

from .._atomic import atomic_open
from ..errors import ConfigError
from ..scene import Scene, load_scene
from .layout import (
    DER_UNITS,
    STATES,
    FmuArray,
    FmuRow,
    SystemLayout,
    fmu_arrays,
    fmu_rows,
    fmu_terminals,
    fmu_variables,
    jacobian_pattern,
    me_rows,
    range_rows,
    system_layout,
)

__all__ = ["build_fmu", "model_identifier", "fmi_include_dir", "compile_command", "binary_path", "C_FLAGS",
           "DEFAULT_OUTPUT", "WINDOWS_CC", "WINDOWS_C_FLAGS", "windows_compiler", "PLATFORMS", "engine_sources",
           "FMI_TYPES", "STATES", "ME_NORM_TOL", "fmu_variables", "dependencies"]

DEFAULT_OUTPUT = Path("fmu") / "dist"

#: The engine's floating-point flags (core/engine/cflags.txt, shared with the Python extension) and the FMU's.
C_FLAGS = (*resources.files("gyrosim.core").joinpath("engine", "cflags.txt").read_text().split(),
           "-Wall", "-Wextra", "-fPIC", "-fvisibility=hidden")
#: The MinGW-w64 cross-compiler of the win64 binary (Debian package gcc-mingw-w64-x86-64).
WINDOWS_CC = "x86_64-w64-mingw32-gcc"
#: The Windows flags: the same engine flags and warnings; no -fPIC / -fvisibility (PE code is position independent,
#: and a DLL exports exactly the functions the FMI headers declare ``__declspec(dllexport)`` on ``_WIN32``);
#: libgcc linked statically, so the DLL imports only the system's DLLs (KERNEL32, msvcrt). MinGW's C99 stdio
#: (``__USE_MINGW_ANSI_STDIO``) formats the log messages (msvcrt's lacks %zu), and the glue's format attributes
#: check against it (``gnu_printf``).
WINDOWS_C_FLAGS = (*(f for f in C_FLAGS if f not in ("-fPIC", "-fvisibility=hidden")),
                   "-D__USE_MINGW_ANSI_STDIO=1", "-static-libgcc")
#: The platforms an FMU may carry: name -> (FMI 2.0 folder, FMI 3.0 folder, library suffix).
PLATFORMS = {"linux": ("linux64", "x86_64-linux", ".so"), "windows": ("win64", "x86_64-windows", ".dll")}

#: The engine's files every FMU is compiled from: the whole of core/engine/ (one engine; the package ships it, as
#: setup.py compiles it), read from the folder so that a file added there is in every FMU; and the glue's (c/).
_ENGINE = tuple(sorted(f.name for f in resources.files("gyrosim.core").joinpath("engine").iterdir()
                       if f.name.endswith((".c", ".h")) or f.name == "cflags.txt"))
_GLUE = ("gyrosim_glue_api.h", "gyrosim_glue_common.h", "gyrosim_num.h", "gyrosim_model.h", "gyrosim_model.c")
#: FMI 3.0's glue besides: array variables and adjoint derivatives (fmi3Functions.c calls it).
_GLUE3 = ("gyrosim_arrays.h", "gyrosim_arrays.c")
_UNITS = {  # unit -> SI base-unit exponents
    "kg.m2": {"kg": 1, "m": 2}, "kg": {"kg": 1}, "m": {"m": 1}, "m/s2": {"m": 1, "s": -2},
    "N.m.s": {"kg": 1, "m": 2, "s": -1}, "s": {"s": 1}, "1": {}, "rad/s": {"rad": 1, "s": -1},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "rad": {"rad": 1}, "kg.m2/s": {"kg": 1, "m": 2, "s": -1},
    "J": {"kg": 1, "m": 2, "s": -2}, "1/s": {"s": -1}, "rad/s2": {"rad": 1, "s": -2},
    # tree scenes
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1}, "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "m/s": {"m": 1, "s": -1}, "W": {"kg": 1, "m": 2, "s": -3},
    "m3/s2": {"m": 3, "s": -2},
    # sliders, springs, forces
    "N": {"kg": 1, "m": 1, "s": -2}, "N/m": {"kg": 1, "s": -2}, "N.s/m": {"kg": 1, "s": -1},
    # contact: Hunt-Crossley's stiffness is kg m^-1/2 s^-2, which FMI's integer exponents cannot write (the unit
    # stays named, without a BaseUnit)
    "s/m": {"s": 1, "m": -1}, "N/m1.5": None, "kg.m3/s": {"kg": 1, "m": 3, "s": -1},
    # a gear between a slider and a hinge (rack and pinion): its ratio
    "m/rad": {"m": 1, "rad": -1}, "rad/m": {"rad": 1, "m": -1},
}
_TOKEN = "@INSTANTIATION_TOKEN@"
#: ``fmi_type`` values: co-simulation, model exchange, or both interfaces in one FMU.
FMI_TYPES = ("cs", "me", "both")
#: | |q| - 1 | beyond which a completed integrator step asks for a step event that renormalises q (GS_ME_NORM_TOL).
ME_NORM_TOL = 1e-3
_LOG_CATEGORIES = (("logStatusWarning", "Log messages with status Warning (this FMU has none)."),
                   ("logStatusError", "Log messages with status Error: illegal calls, invalid values, failed steps."),
                   ("logStatusFatal", "Log messages with status Fatal (this FMU has none)."),
                   ("logEvents", "Log instantiation."))


def _engine_methods() -> tuple[str, ...]:
    """The engine's integrator names by code (the FMU's integrator codes)."""
    from ..core import _engine

    return _engine.METHODS


def engine_sources() -> dict[str, str]:
    """The C sources every FMU is compiled from, ``{file name: text}`` (engine, then glue; no generated config)."""
    eng = resources.files("gyrosim.core").joinpath("engine")
    glue = resources.files(__package__).joinpath("c")
    out = {name: eng.joinpath(name).read_text() for name in _ENGINE}
    out.update({name: glue.joinpath(name).read_text() for name in _GLUE})
    return out


def fmi_include_dir() -> Path:
    """The FMI 2.0 / 3.0 C headers that FMPy ships (``fmpy/c-code``)."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def model_identifier(scene: str | Path | Scene | None = None) -> str:
    """``RigidBody`` for the full model, else the scene name in CamelCase.

    Examples
    --------
    >>> model_identifier(None), model_identifier("heavy_top"), model_identifier("free_body")
    ('RigidBody', 'HeavyTop', 'FreeBody')
    """
    if scene is None:
        return "RigidBody"
    sc = load_scene(scene)
    if sc.name == "full":
        return "RigidBody"
    ident = "".join(p[:1].upper() + p[1:] for p in re.split(r"[^0-9A-Za-z]+", sc.name) if p)
    return ident if ident[:1].isalpha() else "Gyrosim" + ident


def binary_path(fmi_version: int, identifier: str, platform: str = "linux") -> str:
    """Path of the shared library inside the FMU: ``platform`` "linux" (x86-64) or "windows" (x86-64).

    Examples
    --------
    >>> binary_path(2, "HeavyTop"), binary_path(3, "HeavyTop", "windows")
    ('binaries/linux64/HeavyTop.so', 'binaries/x86_64-windows/HeavyTop.dll')
    """
    v2, v3, suffix = PLATFORMS[platform]
    return f"binaries/{v2 if fmi_version == 2 else v3}/{identifier}{suffix}"


def windows_compiler() -> str | None:
    """The MinGW-w64 cross-compiler's path (:data:`WINDOWS_CC` on PATH), or None."""
    return shutil.which(WINDOWS_CC)


def _hexf(x: float) -> str:
    """A C99 hexadecimal floating literal: the exact double, whatever the compiler's decimal rounding."""
    x = float(x)
    if not math.isfinite(x):
        raise ConfigError("start value", x, "a finite number")
    return x.hex()


def _fmt(x) -> str:
    return repr(float(x))


def range_attributes(attrs: dict, v) -> dict:
    """Add the ``min``/``max`` attributes of a Real variable's range (``v``: a :class:`~gyrosim.model.Variable`) to
    ``attrs``: inclusive as FMI has them; an exclusive bound as the next double beyond it (``> 0``:
    ``min="5e-324"``), so that ``[min, max]`` is exactly what the FMU accepts."""
    rng = v.range
    if rng.fmi_min is not None:
        attrs["min"] = _fmt(rng.fmi_min)
    if rng.fmi_max is not None:
        attrs["max"] = _fmt(rng.fmi_max)
    return attrs


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


_KIND_C = {"time": "GS_K_TIME", "param": "GS_K_PARAM", "max_drift": "GS_K_MAX_DRIFT", "input": "GS_K_INPUT",
           "alias": "GS_K_ALIAS", "state": "GS_K_STATE", "output": "GS_K_OUTPUT", "integrator": "GS_K_INTEGRATOR",
           "max_step": "GS_K_MAX_STEP", "work": "GS_K_WORK", "der": "GS_K_DER", "indicator": "GS_K_INDICATOR"}


def _unit_of(rows: list[FmuRow], row: FmuRow) -> str:
    """A variable's unit: its own, or for model exchange's locals the balance's (J) and a derivative's."""
    if row.kind == "work":
        return "J"
    if row.kind == "der":
        unit = next((r.var.unit for r in rows if r.kind == "state" and r.aux == row.index), "J")
        return DER_UNITS[unit]
    return row.var.unit


def range_text(row: FmuRow) -> str:
    """What a value of the parameter of ``row`` must be, from its range."""
    v = row.var
    return v.range.text(v.unit) + (f" (the range of scene parameter {row.name})" if row.kind == "alias" else "")


def _refusals(sc: Scene, rows: list[FmuRow]) -> dict[int, str]:
    """What the model says of a value just outside each checked variable's range (the words after "is not
    allowed: "), by position in ``rows``: the FMU refuses in the model's words. :func:`range_text` where the model
    gives none."""
    from ..model import Model

    model, out = Model(sc), {}
    for i, v in range_rows(rows):
        rng = v.range
        if math.isfinite(rng.min):
            bad = rng.min if rng.exclusive_min else float(np.nextafter(rng.min, -math.inf))
        else:
            bad = rng.max if rng.exclusive_max else float(np.nextafter(rng.max, math.inf))
        try:
            model.set(rows[i].name, bad)
        except ConfigError as e:
            head, sep, words = str(e).partition(" is not allowed: ")
            named = head.rpartition(" = ")[0]   # the model may name a body's variable by its short name
            if sep and named and (rows[i].name == named or rows[i].name.endswith("." + named)):
                out[i] = words
                continue
        out[i] = range_text(rows[i])
    return out


def _ranges(sc: Scene, rows: list[FmuRow]) -> tuple[list[str], dict[int, int]]:
    """The GS_RANGES rows and, by position in ``rows``, the row of each variable checked against its range."""
    table, where = [], {}
    words = _refusals(sc, rows)
    for i, v in range_rows(rows):
        rng = v.range
        kinds = []
        for bound, open_ in ((rng.min, rng.exclusive_min), (rng.max, rng.exclusive_max)):
            kinds.append(("GS_BOUND_EXCLUSIVE" if open_ else "GS_BOUND_INCLUSIVE") if math.isfinite(bound)
                         else "GS_BOUND_NONE")
        lo = _hexf(rng.min) if math.isfinite(rng.min) else "0.0"
        hi = _hexf(rng.max) if math.isfinite(rng.max) else "0.0"
        where[i] = len(table)
        table.append(f"{{{lo}, {hi}, {kinds[0]}, {kinds[1]}, {_c_string(words[i])}}}")
    return table, where


def _config_header(sc: Scene, lay: SystemLayout, rows: list[FmuRow], ident: str, token: str, fmi_version: int,
                   integrator: str, fmi_type: str) -> str:
    """The generated ``gyrosim_config.h``: the scene's system, variable table and start values, as data for the one
    glue (c/gyrosim_model.h)."""
    has_me = fmi_type in ("me", "both")
    table = ['{GS_K_TIME, 0, 0, 0, "time", "s", -1}' if fmi_version == 3 else '{GS_K_NONE, 0, 0, 0, "", "", -1}']
    ranges, range_of = _ranges(sc, rows)
    for i, r in enumerate(rows + (me_rows(lay, rows) if has_me else [])):
        table.append(f"{{{_KIND_C[r.kind]}, {r.index}, {r.aux}, {int(r.nonneg)}, {_c_string(r.name)}, "
                     f"{_c_string(_unit_of(rows, r) or '')}, {range_of.get(i, -1)}}}")
    targets = []
    if sc.aliases:
        from ..kernel_tree import alias_targets, tree_layout

        for ai, a in enumerate(sc.aliases):
            for col, f, nonneg, label in alias_targets(sc, tree_layout(sc), a):
                targets.append(f"{{{ai}, {col}, {_hexf(f)}, {int(nonneg)}, {_c_string(label)}}}")

    def arr(values, fmt=_hexf, empty="0.0"):
        return "{" + (", ".join(fmt(v) for v in values) if len(values) else empty) + "}"

    lines = [
        "/* Generated by gyrosim.fmu.build: the scene's system, variable table and start values. */",
        "#ifndef GYROSIM_CONFIG_H", "#define GYROSIM_CONFIG_H", "",
        f"#define FMI_VERSION {fmi_version}",
        f"#define MODEL_IDENTIFIER {ident}",
        f'#define MODEL_IDENTIFIER_STRING "{ident}"',
        f'#define INSTANTIATION_TOKEN "{token}"',
        f"#define GS_SCENE_NAME {_c_string(sc.name)}", "",
        f"#define GS_HAS_CS {int(fmi_type in ('cs', 'both'))}   /* the interfaces: --fmi-type {fmi_type} */",
        f"#define GS_HAS_ME {int(has_me)}", "",
        f"/* the system (gs_sys_init): {len(sc.body_names)} bodies ({', '.join(sc.body_names[:10])}) */",
        "#define GS_SYS_DESC " + arr(lay.desc, str),
        f"#define GS_SYS_NY {lay.ny}   /* state */",
        f"#define GS_SYS_NP {lay.np}   /* parameter row */",
        f"#define GS_SYS_NOUT {lay.nout}   /* output row */",
        f"#define GS_SYS_NDY {lay.ndy}   /* derivative row: coordinates, then work integrals */",
        f"#define GS_SYS_UNITS {lay.units}   /* units of hint, stats, anchors */",
        f"#define GS_SYS_NEX {lay.nex}   /* anchor values per unit */",
        f"#define GS_SYS_NX {lay.nx}   /* model exchange's continuous states */",
        f"#define GS_NZ {len(lay.indicators)}   /* model exchange's event indicators (impact stops) */",
        f"#define GS_ME_WORK_STATES {int(lay.work_states)}   /* the work integrals are continuous states */",
        f"#define GS_ME_STATES_TEXT {_c_string(lay.states_text)}",
        "#define GS_UNIT_NAMES " + arr(lay.unit_names, _c_string), "",
        "/* start values: the parameter row (inputs 0) and the state (the monitor's part set at initialisation) */",
        "#define GS_START_P " + arr(lay.p0),
        "#define GS_START_Y " + arr(lay.y0),
        f"#define GS_START_INTEGRATOR_CODE {_engine_methods().index(integrator)}   /* {integrator} */",
        f"#define GS_START_MAX_STEP {_hexf(sc.max_step)}   /* {_fmt(sc.max_step)} */",
        f"#define GS_START_TOLERANCE {_hexf(sc.tolerance)}   /* {_fmt(sc.tolerance)} */",
        f"#define GS_INTEGRATOR_LIST {_c_string(', '.join(sc.integrators))}", "",
        "/* scene parameters: their start values, and {alias, parameter-row slot, factor, >= 0, target} of every "
        "target (alias -1: none) */",
        f"#define GS_N_ALIASES {len(sc.aliases)}",
        "#define GS_START_ALIASES " + arr([a.value for a in sc.aliases]),
        "#define GS_ALIAS_TARGETS {" + (", ".join(targets) if targets else '{-1, 0, 0.0, 0, ""}') + "}", "",
        "/* the parameters' ranges: {lo, hi, lower bound, upper bound, what the message says} (GS_RANGES row of "
        "each GS_VARS row) */",
        "#define GS_RANGES {" + (", ".join(ranges) if ranges else
                                 '{0.0, 0.0, GS_BOUND_NONE, GS_BOUND_NONE, "a finite number"}') + "}", "",
        "/* the quaternions' names (in the order of gs_sys_quat_slot) */",
        "#define GS_QUAT_NAMES " + arr([n for _, n in lay.quats], _c_string, '""'),
        "/* model exchange: the continuous states' nominal values */",
        "#define GS_NOMINALS " + arr(lay.nominals[:lay.nx]), "",
        "/* value reference -> {kind, index, aux, flags (1: >= 0), name, unit, range (GS_RANGES row, -1: none)} */",
        "#define GS_VARS { \\\n    " + ", \\\n    ".join(table) + "}",
        *(_arrays_config(sc, lay, rows, len(table)) if fmi_version == 3 else []),
        "", "#endif", "",
    ]
    return "\n".join(lines)


def _platforms_note(platforms) -> str:
    if "windows" in platforms:
        return ("Binaries: Linux x86-64 and Windows x86-64 (cross-compiled with MinGW-w64); other platforms build "
                "from sources/.")
    return ("Binaries: Linux x86-64 only (no MinGW-w64 cross-compiler at build time, so no Windows binary); "
            "other platforms build from sources/.")


def source_files(interface: ET.Element, sources) -> None:
    """FMI 2.0's ``<SourceFiles>`` of an interface element: the C files among ``sources``."""
    sf = ET.SubElement(interface, "SourceFiles")
    for name in sources:
        if name.endswith(".c"):
            ET.SubElement(sf, "File", name=name)


def content_token(*parts: str) -> str:
    """The instantiation token (FMI 2.0 guid) of an FMU: a UUID from the SHA-256 of its texts, so that the same
    sources give the same token (reproducible builds) and other sources another."""
    h = hashlib.sha256()
    for part in parts:
        h.update(part.encode())
    return "{" + str(uuid.UUID(bytes=h.digest()[:16], version=5)) + "}"


def description_head(sc: Scene, ident: str, token: str, fmi_version: int, desc: str, sources, fmi_type: str,
                     units, n_indicators: int = 0) -> ET.Element:
    """The root of a model description up to its variables: the attributes, the interfaces (co-simulation, model
    exchange), the units (``units``, and ``s``), log categories and the default experiment of scene ``sc``."""
    from .. import __version__

    has_cs, has_me = fmi_type in ("cs", "both"), fmi_type in ("me", "both")
    root = ET.Element("fmiModelDescription")
    root.set("fmiVersion", "2.0" if fmi_version == 2 else "3.0")
    root.set("modelName", ident)
    root.set("guid" if fmi_version == 2 else "instantiationToken", token)
    root.set("description", desc)
    root.set("generationTool", f"gyrosim {__version__}")
    root.set("variableNamingConvention", "flat")
    if fmi_version == 2:
        root.set("numberOfEventIndicators", str(n_indicators))
    if has_me:
        me = ET.SubElement(root, "ModelExchange")
        me.set("modelIdentifier", ident)
        if fmi_version == 2:
            attrs = {"needsExecutionTool": "false", "completedIntegratorStepNotNeeded": "false",
                     "canBeInstantiatedOnlyOncePerProcess": "false", "canNotUseMemoryManagementFunctions": "true",
                     "canGetAndSetFMUstate": "true", "canSerializeFMUstate": "true",
                     "providesDirectionalDerivative": "true"}
        else:
            attrs = {"needsExecutionTool": "false", "canBeInstantiatedOnlyOncePerProcess": "false",
                     "canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
                     "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true",
                     "needsCompletedIntegratorStep": "true"}
        for k, v in attrs.items():
            me.set(k, v)
        if fmi_version == 2:
            source_files(me, sources)
    if not has_cs:
        cs = ET.Element("CoSimulation")   # not written
    else:
        cs = ET.SubElement(root, "CoSimulation")
    cs.set("modelIdentifier", ident)
    common = {"needsExecutionTool": "false", "canHandleVariableCommunicationStepSize": "true",
              "canBeInstantiatedOnlyOncePerProcess": "false", "maxOutputDerivativeOrder": "0"}
    if fmi_version == 2:
        common.update({"canInterpolateInputs": "false", "canRunAsynchronuously": "false",
                       "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "true",
                       "canSerializeFMUstate": "true", "providesDirectionalDerivative": "true"})
    else:
        common.update({"canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
                       "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "true",
                       # event mode, early return, intermediate update (fmi3Functions.c, docs/fmu.md)
                       "hasEventMode": "true", "mightReturnEarlyFromDoStep": "true",
                       "canReturnEarlyAfterIntermediateUpdate": "true", "providesIntermediateUpdate": "true"})
    for k, v in common.items():
        cs.set(k, v)
    if fmi_version == 2:
        source_files(cs, sources)
    units = sorted(set(units) | {"s"})
    ud = ET.SubElement(root, "UnitDefinitions")
    for u in units:
        ue = ET.SubElement(ud, "Unit", name=u)
        if _UNITS[u] is not None:
            ET.SubElement(ue, "BaseUnit", {k: str(e) for k, e in _UNITS[u].items()})
    lc = ET.SubElement(root, "LogCategories")
    for name, d in _LOG_CATEGORIES:
        ET.SubElement(lc, "Category", name=name, description=d)
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=_fmt(sc.stop_time),
                  tolerance=_fmt(sc.tolerance), stepSize=_fmt(sc.output_interval))
    return root


def _me_note(lay: SystemLayout) -> str:
    """The model description's words on model exchange."""
    note = (f"Model exchange: the continuous states are {lay.states_text}, their derivatives the engine's right-hand "
            "side; the host's solver integrates them (integrator, max_step, max_drift and the tolerance act in "
            "co-simulation only).")
    if lay.quats:
        note += (f" |q| is a first integral of the flow, so it drifts by the solver's error only: when a completed "
                 f"integrator step finds | |q| - 1 | > {ME_NORM_TOL:g}, the FMU asks for a step event and "
                 "renormalises q in the event update (valuesOfContinuousStatesChanged); the derived outputs use q "
                 "normalised.")
    if not lay.indicators:
        return note + " No event indicators."
    n = len(lay.indicators)
    return note + (f" {n} event indicator{'s' if n > 1 else ''} (numberOfEventIndicators in FMI 2.0, EventIndicator "
                   "in FMI 3.0): " + ", ".join(f"{name} ({unit})" for name, unit in lay.indicators)
                   + ": the distance to an impact stop (>= 0 within the stops); where one reaches 0 the FMU's event "
                   "update applies the impact (the joint's rate reversed and scaled by its restitution).")


def dependencies(lay: SystemLayout, rows: list[FmuRow], has_me: bool) -> dict[int, list[int]]:
    """The ModelStructure's dependencies: ``{value reference of an output or a state derivative: value references of
    the knowns it depends on}``; the knowns are those of the directional derivatives (the inputs, and with model
    exchange the continuous states), from the system's Jacobian pattern (:func:`~gyrosim.fmu.layout.jacobian_pattern`).
    As the glue computes them: a coordinate output depends on itself; a derivative other than dq/dt, or a derived
    output, that depends on one component of a quaternion depends on all four (it sees q normalised); energy_error also
    on its balance where that is a state."""
    ddy, dout = jacobian_pattern(lay, rows)
    state_vr = {r.aux: vr for vr, r in enumerate(rows, start=1) if r.kind == "state"}
    input_vr = [vr for vr, r in enumerate(rows, start=1) if r.kind == "input"]
    in_quat = {lay.coord_index[q] + a: lay.coord_index[q] for q, _ in lay.quats for a in range(4)}
    extra = me_rows(lay, rows) if has_me else []
    work_vr = {r.aux: vr for vr, r in enumerate(extra, start=len(rows) + 1) if r.kind == "work"}

    def knowns(row, raw: bool) -> list[int]:
        out = [vr for j, vr in enumerate(input_vr) if row[lay.ncoord + j]]
        if has_me:
            cols = {j for j in range(lay.ncoord) if row[j]}
            if not raw:
                cols |= {in_quat[j] + a for j in cols if j in in_quat for a in range(4)}
            out += [state_vr[j] for j in cols if j in state_vr]
        return sorted(out)

    deps = {}
    for vr, r in enumerate(rows, start=1):
        if r.kind == "state":
            deps[vr] = [vr] if has_me else []
        elif r.kind == "output":
            deps[vr] = knowns(dout[r.index], False) + ([work_vr[r.index]] if r.index in work_vr else [])
    for vr, r in enumerate(extra, start=len(rows) + 1):
        if r.kind == "der":
            deps[vr] = knowns(ddy[r.index], r.index in in_quat)
    return deps


def _model_description(sc: Scene, lay: SystemLayout, rows: list[FmuRow], ident: str, token: str, fmi_version: int,
                       integrator: str, sources, fmi_type: str = "cs", platforms=("linux",)) -> str:
    """modelDescription.xml: the variables of ``rows`` (value references from 1; FMI 3.0's time at 0), and with model
    exchange :func:`~gyrosim.fmu.layout.me_rows` after them."""
    has_me = fmi_type in ("me", "both")
    integ = [i if i != "exact" or sc.exact_start() is None else "exact (a torque-free body or a Lagrange top only)"
             for i in sc.integrators]
    kind = {"cs": "co-simulation", "me": "model exchange", "both": "co-simulation and model exchange"}[fmi_type]
    names = sc.body_names
    desc = (f"gyrosim {sc.name if sc.name != 'full' else 'rigid body (full model)'}: "
            f"{sc.description or 'rigid body'}. Native FMU (the gyrosim C engine, no Python), {kind}; "
            f"{len(names)} bod{'y' if len(names) == 1 else 'ies'}"
            + ((f" ({', '.join(names)}) joined by joints" if len(names) > 1 else
                f" ({names[0]}) on a {sc.tree[0].joint} joint") if lay.work_states else "")
            + "; integrators " + ", ".join(integ) + "." + (" " + _me_note(lay) if has_me else "") + " "
            + _platforms_note(platforms))
    extra = me_rows(lay, rows) if has_me else []
    all_rows = rows + extra
    units = {_unit_of(rows, r) for r in all_rows} - {""}
    root = description_head(sc, ident, token, fmi_version, desc, sources, fmi_type, units,
                            len(lay.indicators) if has_me else 0)
    mv = ET.SubElement(root, "ModelVariables")
    if fmi_version == 3:
        ET.SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", unit="s", description="simulation time")
    state_vr = {r.aux: vr for vr, r in enumerate(rows, start=1) if r.kind == "state"}
    state_vr.update({r.index: vr for vr, r in enumerate(extra, start=len(rows) + 1) if r.kind == "work"})
    outputs, initial_unknowns, derivatives, indicators = [], [], [], []
    for vr, r in enumerate(all_rows, start=1):   # the value reference is also the 1-based index (FMI 2.0)
        v = r.var
        start, nominal, derivative = None, None, None
        if v is not None:
            attrs = {"name": r.name, "valueReference": str(vr), "causality": v.causality,
                     "variability": v.variability, "description": v.description}
            if r.kind == "output":
                outputs.append(vr)
                attrs["initial"] = "calculated"
                initial_unknowns.append(vr)
            elif r.kind == "state":
                outputs.append(vr)
                attrs["initial"] = "exact"
                start = v.start
            elif v.causality == "parameter":
                attrs["initial"] = "exact"
                start = integrator if v.type == "String" else v.start
            elif r.kind == "indicator":
                indicators.append(vr)
            else:
                start = v.start
            if has_me and r.kind == "state" and lay.nominals[r.aux] != 1.0:
                nominal = _fmt(lay.nominals[r.aux])
            vtype = v.type
        else:
            vtype = "Real"
            if r.kind == "work":
                what = ("the energy the work-energy balance expects, E(0) + W_inputs - W_dissipation (model "
                        "exchange's continuous state of the work; energy_error = energy - energy_expected)")
                if lay.nominals[r.index] != 1.0:
                    nominal = _fmt(lay.nominals[r.index])
            else:
                what = f"derivative of {r.name[4:-1]} (model exchange: the engine's right-hand side)"
                derivative = str(state_vr[r.index])
                derivatives.append(vr)
            attrs = {"name": r.name, "valueReference": str(vr), "causality": "local", "variability": "continuous",
                     "description": what}
            if r.kind == "work":
                attrs["initial"] = "calculated"
            initial_unknowns.append(vr)
        unit = _unit_of(rows, r)
        if fmi_version == 2:
            sv = ET.SubElement(mv, "ScalarVariable", attrs)
            t = ET.SubElement(sv, "Real" if vtype == "Real" else "String")
            if start is not None:
                t.set("start", start if isinstance(start, str) else _fmt(start))
            if vtype == "Real" and unit:
                t.set("unit", unit)
            if vtype == "Real" and v is not None:
                range_attributes(t.attrib, v)
            if nominal is not None:
                t.set("nominal", nominal)
            if derivative is not None:
                t.set("derivative", derivative)
        elif vtype == "Real":
            if fmi_type != "me" and r.kind in ("output", "state"):   # readable in intermediate update mode
                attrs["intermediateUpdate"] = "true"
            if start is not None:
                attrs["start"] = _fmt(start)
            if unit:
                attrs["unit"] = unit
            if v is not None:
                range_attributes(attrs, v)
            if nominal is not None:
                attrs["nominal"] = nominal
            if derivative is not None:
                attrs["derivative"] = derivative
            ET.SubElement(mv, "Float64", attrs)
        else:
            se = ET.SubElement(mv, "String", attrs)
            ET.SubElement(se, "Start", value=str(start))
    deps = dependencies(lay, rows, has_me)
    if fmi_version == 3:   # the arrays after every scalar
        array_variables(mv, lay, all_rows, fmu_arrays(sc, lay, rows), outputs, initial_unknowns, deps)
    initial_unknowns.sort()
    model_structure(root, fmi_version, outputs, derivatives, initial_unknowns, deps, indicators)
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def model_structure(root: ET.Element, fmi_version: int, outputs, derivatives, initial_unknowns, deps,
                    indicators=()) -> None:
    """The ModelStructure of value references ``outputs``, ``derivatives`` and ``initial_unknowns`` (in FMI 2.0 the
    1-based index in ModelVariables, which is the value reference here: FMI 2.0 has no variable at 0); ``deps``
    gives the outputs' and derivatives' ``dependencies`` (value references of the knowns: continuous states and
    inputs, those of the directional derivatives). The initial unknowns carry none: they depend on every known of
    the initialisation (parameters and start values), which the directional derivatives do not take."""
    ms = ET.SubElement(root, "ModelStructure")

    def dep(attrs, vr):
        if vr in deps:
            attrs["dependencies"] = " ".join(str(k) for k in deps[vr])
        return attrs

    if fmi_version == 2:
        oe = ET.SubElement(ms, "Outputs")
        for vr in outputs:
            ET.SubElement(oe, "Unknown", dep({"index": str(vr)}, vr))
        if derivatives:
            de = ET.SubElement(ms, "Derivatives")
            for vr in derivatives:
                ET.SubElement(de, "Unknown", dep({"index": str(vr)}, vr))
        ie = ET.SubElement(ms, "InitialUnknowns")
        for vr in initial_unknowns:
            ET.SubElement(ie, "Unknown", index=str(vr))
    else:
        for vr in outputs:
            ET.SubElement(ms, "Output", dep({"valueReference": str(vr)}, vr))
        for vr in derivatives:
            ET.SubElement(ms, "ContinuousStateDerivative", dep({"valueReference": str(vr)}, vr))
        for vr in initial_unknowns:
            ET.SubElement(ms, "InitialUnknown", valueReference=str(vr))
        for vr in indicators:   # FMI 3.0 names its event indicators (FMI 2.0: numberOfEventIndicators)
            ET.SubElement(ms, "EventIndicator", valueReference=str(vr))


#: FMI 3.0's terminals (every FMI 3.0 FMU carries them: :func:`terminals_and_icons`).
TERMINALS_FILE = "terminalsAndIcons/terminalsAndIcons.xml"


def _arrays_config(sc: Scene, lay: SystemLayout, rows: list[FmuRow], vr0: int) -> list[str]:
    """The generated configuration's array variables (FMI 3.0; gyrosim_arrays.c): value references from ``vr0`` (the
    first after every scalar), each ``{name, elements, first row of GS_ARRAY_ELEMS}``, and every element ``{value
    reference of its scalar (0: none), parameter-row slot of a fixed element (-1: 0), its name in messages}``."""
    arrays, elems = [], []
    for a in fmu_arrays(sc, lay, rows):
        arrays.append(f"{{{_c_string(a.name)}, {len(a.elements)}, {len(elems)}}}")
        elems += [f"{{{vr}u, {slot}, {_c_string(label)}}}" for vr, slot, label in zip(a.elements, a.fixed, a.labels)]
    return ["", "/* FMI 3.0 array variables (gyrosim_arrays.c): {name, elements, first element row}, value references "
            "GS_ARRAY_VR0 onwards; an element {scalar's value reference (0: none), fixed parameter-row slot "
            "(-1: 0), name} */",
            f"#define GS_N_ARRAYS {len(arrays)}", f"#define GS_ARRAY_VR0 {vr0}u",
            "#define GS_ARRAYS {" + (", ".join(arrays) if arrays else '{"", 0, 0}') + "}",
            "#define GS_ARRAY_ELEMS { \\\n    " + (", \\\n    ".join(elems) if elems else '{0u, -1, ""}') + "}"]


def array_variables(mv: ET.Element, lay: SystemLayout, rows: list[FmuRow], arrays: list[FmuArray], outputs: list,
                    initial_unknowns: list, deps: dict) -> None:
    """FMI 3.0's array variables ``arrays`` (:func:`~gyrosim.fmu.layout.fmu_arrays`) into ModelVariables ``mv``,
    value references after the variables ``rows`` (every scalar, model exchange's included): ``<Float64>`` with its
    ``<Dimension>`` elements, causality, variability, initial and unit those of its scalars, the start values theirs
    (row-major; a fixed element's from the parameter row), and where they share one, their range. An output is in
    ``outputs`` with the union of its scalars' dependencies (``deps``, extended), a calculated one also in
    ``initial_unknowns``. No array is declared ``intermediateUpdate`` (fmi3InstantiateCoSimulation's required
    intermediate variables are scalars)."""
    for k, a in enumerate(arrays):
        vr = len(rows) + 1 + k
        scalars = [rows[e - 1] for e in a.elements if e]
        first, v = scalars[0], scalars[0].var
        attrs = {"name": a.name, "valueReference": str(vr), "causality": v.causality,
                 "variability": v.variability, "description": a.what}
        if first.kind == "output":
            attrs["initial"] = "calculated"
        else:
            attrs["initial"] = "exact"
            attrs["start"] = " ".join(_fmt(rows[e - 1].var.start if e else (lay.p0[f] if f >= 0 else 0.0))
                                      for e, f in zip(a.elements, a.fixed))
        if v.unit:
            attrs["unit"] = v.unit
        ranges = {tuple(sorted(range_attributes({}, r.var).items())) for r in scalars}
        if len(scalars) == len(a.elements) and len(ranges) == 1:
            attrs.update(dict(next(iter(ranges))))
        el = ET.SubElement(mv, "Float64", attrs)
        for n in a.shape:
            ET.SubElement(el, "Dimension", start=str(n))
        if v.causality == "output":
            outputs.append(vr)
            if attrs["initial"] == "calculated":
                initial_unknowns.append(vr)
            dep = [deps[e] for e in a.elements if e in deps]
            if dep:
                deps[vr] = sorted(set().union(*dep))


def terminals_and_icons(sc: Scene, rows: list[FmuRow]) -> str:
    """``terminalsAndIcons/terminalsAndIcons.xml`` (FMI 3.0, fmi3TerminalsAndIcons.xsd): the terminals of
    :func:`~gyrosim.fmu.layout.fmu_terminals`, their members ``signal`` variables (no icon)."""
    root = ET.Element("fmiTerminalsAndIcons", fmiVersion="3.0")
    ts = ET.SubElement(root, "Terminals")
    for t in fmu_terminals(sc, rows):
        te = ET.SubElement(ts, "Terminal", name=t.name, matchingRule=t.rule, terminalKind=t.kind, description=t.what)
        for member, var in t.members:
            ET.SubElement(te, "TerminalMemberVariable", variableName=var, memberName=member, variableKind="signal")
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _build_description(ident: str, sources) -> str:
    flags = " ".join(f for f in C_FLAGS if f.startswith(("-std", "-O", "-ff", "-fno")))
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    bc = ET.SubElement(root, "BuildConfiguration", modelIdentifier=ident,
                       description=f"C11; compile with {flags} (no fused multiply-add, no fast-math) to reproduce "
                                   "gyrosim's Model.step to the bit; link libm")
    sfs = ET.SubElement(bc, "SourceFileSet", language="C11", compilerOptions=flags)
    for s in sources:
        if s.endswith(".c"):
            ET.SubElement(sfs, "SourceFile", name=s)
    ET.SubElement(bc, "Library", name="m", external="true", description="the C math library (libm)")
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def compile_command(src_dir: Path, out: Path, fmi_version: int, cc: str | None = None,
                    platform: str = "linux") -> list[str]:
    """The compiler command that builds the FMU's shared library from ``src_dir`` (the FMU's sources: every engine
    unit, the glue, the FMI functions); ``platform`` "windows" cross-compiles the DLL with MinGW-w64 (``cc`` default
    :data:`WINDOWS_CC`)."""
    if platform == "windows":
        cc, flags = cc or WINDOWS_CC, WINDOWS_C_FLAGS
    else:
        cc, flags = cc or os.environ.get("CC", "gcc"), C_FLAGS
    srcs = [*ENGINE_UNITS, "gyrosim_model.c", *(["gyrosim_arrays.c"] if fmi_version == 3 else []),
            f"fmi{fmi_version}Functions.c"]
    return [cc, *flags, "-shared", f"-I{src_dir}", f"-I{fmi_include_dir()}",
            *[str(src_dir / s) for s in srcs], "-o", str(out), "-Wl,--no-undefined", "-lm"]


#: The engine's translation units: the same text in every FMU, so compiled once per compiler, flags and text and kept
#: (:func:`_engine_objects`); an FMU build then compiles only its glue.
ENGINE_UNITS = tuple(f for f in _ENGINE if f.endswith(".c"))
#: The headers the engine's units include (and nothing else: the glue's headers and the generated configuration
#: are not the engine's).
ENGINE_HEADERS = tuple(f for f in _ENGINE if f.endswith(".h"))


def object_cache_dir() -> Path | None:
    """Where compiled engine objects are kept: ``$GYROSIM_CACHE_DIR/fmu-objects``, else
    ``$XDG_CACHE_HOME/gyrosim/fmu-objects`` (``~/.cache``); None when it cannot be created (then every build
    compiles everything)."""
    base = os.environ.get("GYROSIM_CACHE_DIR")
    root = Path(base) if base else Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "gyrosim"
    d = root / "fmu-objects"
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError:
        return None
    return d if os.access(d, os.W_OK) else None


_CC_VERSION: dict = {}


def _cc_identity(cc: str) -> str:
    if cc not in _CC_VERSION:
        try:
            r = subprocess.run([cc, "--version"], capture_output=True, text=True)
            _CC_VERSION[cc] = (shutil.which(cc) or cc) + "\n" + r.stdout
        except OSError:
            _CC_VERSION[cc] = ""
    return _CC_VERSION[cc]


def _engine_objects(src_dir: Path, cc: str, flags, platform: str, units) -> tuple[list[str], list]:
    """The engine's objects for this compiler, flags and source text: from the cache, or compiled into it (side
    by side, written beside their name and renamed into place, so builds running at once never see half an
    object). Returns (object paths, [(unit, command, Popen)] still compiling) or ([], []) without a cache. The
    object is what the one-command build would compile (no link-time optimisation: each file is its own unit)."""
    cache = object_cache_dir()
    ident = _cc_identity(cc)
    if cache is None or not ident:
        return [], []
    # every engine text in every key: a unit may include another (tree_cs.c includes tree.c)
    headers = "".join((src_dir / h).read_text() for h in (*ENGINE_HEADERS, *units) if (src_dir / h).is_file())
    objs, jobs = [], []
    for unit in units:
        key = hashlib.sha256("\0".join((ident, " ".join(flags), platform, headers,
                                         (src_dir / unit).read_text())).encode()).hexdigest()[:32]
        obj = cache / f"{unit[:-2]}-{key}.o"
        objs.append(str(obj))
        if obj.is_file():
            continue
        # unique per process and thread: builds on a thread pool compile the same unit side by side
        part = obj.with_name(f".{obj.name}.{os.getpid()}.{threading.get_ident()}.{len(jobs)}.tmp")
        cmd = [cc, *flags, f"-I{src_dir}", "-c", str(src_dir / unit), "-o", str(part)]
        jobs.append((platform, cmd, subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                      text=True), part, obj))
    return objs, jobs


def build_fmu(scene: str | Path | Scene | None = None, fmi_version: int = 2,
              output_dir: str | Path = DEFAULT_OUTPUT, *, integrator: str | None = None,
              cc: str | None = None, fmi_type: str = "both", windows: bool | None = None) -> Path:
    """Build ``<output_dir>/<ModelIdentifier>.fmu``: an FMU whose binary is the C engine.

    Parameters
    ----------
    scene : str, Path, Scene or None
        Embedded scene name, TOML path or :class:`~gyrosim.scene.Scene`; ``None`` is the full model
        (``RigidBody.fmu``) with every variable of fmu/README.md. Every body of the scene is exported; the
        variables are :meth:`Scene.variables <gyrosim.scene.Scene.variables>`, the integrators
        :attr:`Scene.integrators <gyrosim.scene.Scene.integrators>`.
    fmi_version : {2, 3}
    output_dir : path
        Created if missing.
    fmi_type : {"cs", "me", "both"}
        The interfaces: co-simulation (the engine's integrators step the model), model exchange (the host's
        solver integrates the system's coordinates) or both in one FMU. ``gyrosim fmu build``
        defaults to ``both``; this function to ``cs`` (the variables then are exactly ``Model.variables``:
        model exchange adds the state derivatives ``der(...)``).
    integrator : str, optional
        Start value of the ``integrator`` parameter (default the scene's).
    cc : str, optional
        C compiler (default ``$CC`` or ``gcc``).
    windows : bool, optional
        Also carry a win64 binary, cross-compiled with MinGW-w64 (:data:`WINDOWS_CC`). ``None`` (default): when that
        compiler is on PATH; ``True``: required (RuntimeError without it); ``False``: Linux only. The model
        description says which platforms the FMU carries.

    Returns
    -------
    Path of the FMU.

    Raises
    ------
    ConfigError
        An unknown FMI version, FMI type or integrator ('exact' on a scene with torques).
    RuntimeError
        The C compiler failed or warned (its output in the message).
    OSError
        The output folder cannot be written.

    Every check runs before the compiler; the FMU is written beside its target and renamed into place, so an
    existing ``<ModelIdentifier>.fmu`` is replaced by a complete FMU or left as it was.
    """
    if fmi_version not in (2, 3):
        raise ConfigError("fmi_version", fmi_version, "2 or 3")
    if fmi_type not in FMI_TYPES:
        raise ConfigError("fmi_type", fmi_type, "one of " + ", ".join(FMI_TYPES))
    sc = load_scene(scene)
    integrator = sc.integrator if integrator is None else integrator
    if integrator not in sc.integrators:   # the integrators the scene's system takes
        raise ConfigError("integrator", integrator, "one of " + ", ".join(sc.integrators))
    if integrator == "exact" and sc.exact_start() is not None:
        raise ConfigError("integrator", integrator, "a general integrator: 'exact' solves a torque-free body or a "
                          f"Lagrange top only, and scene {sc.name!r} starts with {sc.exact_start()}")
    ident = model_identifier(scene)
    win_cc = windows_compiler() if windows is not False else None
    if windows and win_cc is None:
        raise RuntimeError(f"the Windows binary needs the MinGW-w64 cross-compiler {WINDOWS_CC!r} on PATH "
                           "(Debian/Ubuntu: apt-get install gcc-mingw-w64-x86-64)")
    platforms = ("linux", "windows") if win_cc else ("linux",)
    texts = engine_sources()
    for name in (*(_GLUE3 if fmi_version == 3 else ()), f"fmi{fmi_version}Functions.c"):
        texts[name] = resources.files(__package__).joinpath("c", name).read_text()
    sources = [*texts, "gyrosim_config.h"]
    # a deterministic token: a hash of everything the FMU is made of (with a placeholder for the token itself)
    lay = system_layout(sc)
    rows = fmu_rows(sc, lay)
    md = _model_description(sc, lay, rows, ident, _TOKEN, fmi_version, integrator, sources, fmi_type, platforms)
    config = _config_header(sc, lay, rows, ident, _TOKEN, fmi_version, integrator, fmi_type)
    token = content_token(md, config, *texts.values())
    md, config = md.replace(_TOKEN, token), config.replace(_TOKEN, token)
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    fmu_path = output_dir / f"{ident}.fmu"
    with tempfile.TemporaryDirectory(prefix="gyrosim_fmu_") as tmp:
        root = Path(tmp)
        src_dir = root / "sources"
        src_dir.mkdir()
        for name, text in texts.items():
            (src_dir / name).write_text(text)
        (src_dir / "gyrosim_config.h").write_text(config)
        if fmi_version == 3:
            (src_dir / "buildDescription.xml").write_text(_build_description(ident, sources))
        (root / "modelDescription.xml").write_text(md)
        if fmi_version == 3:
            (root / "terminalsAndIcons").mkdir()
            (root / TERMINALS_FILE).write_text(terminals_and_icons(sc, rows))
        # the engine's objects: compiled once per compiler, flags and text (a cache shared by builds), side by side
        # for the platforms; then each platform's library from them and the glue
        plans, pending = [], []
        for platform in platforms:
            so = root / binary_path(fmi_version, ident, platform)
            so.parent.mkdir(parents=True)
            cmd = (compile_command(src_dir, so, fmi_version, win_cc, "windows")
                   if platform == "windows" else compile_command(src_dir, so, fmi_version, cc))
            try:
                flags = cmd[1:cmd.index("-shared")]
                objs, jobs = _engine_objects(src_dir, cmd[0], flags, platform, ENGINE_UNITS)
            except FileNotFoundError:
                objs, jobs = [], []
            if objs:  # each engine source replaced by its object, in place: the same link, the same bits
                at = {str(src_dir / u): o for u, o in zip(ENGINE_UNITS, objs)}
                cmd = [at.get(c, c) for c in cmd]
            plans.append((platform, cmd))
            pending += jobs
        failed = []
        for platform, ucmd, p, part, obj in pending:
            out, err = p.communicate()
            if p.returncode != 0 or out.strip() or err.strip():
                failed.append(f"compiling the FMU ({platform}) failed or warned:\n{' '.join(ucmd)}\n{out}{err}")
                with contextlib.suppress(OSError):
                    part.unlink()
            else:
                os.replace(part, obj)
        if failed:
            raise RuntimeError("\n".join(failed))
        jobs = []   # the platforms' compilers run side by side
        for platform, cmd in plans:
            try:
                jobs.append((platform, cmd, subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                                              text=True)))
            except FileNotFoundError:
                for _, _, p in jobs:
                    p.communicate()
                raise RuntimeError(f"C compiler {cmd[0]!r} not found: the FMU is compiled at build time "
                                   "(install gcc, or set CC)") from None
        for platform, cmd, p in jobs:
            out, err = p.communicate()
            if p.returncode != 0 or out.strip() or err.strip():
                for _, _, other in jobs:
                    other.communicate()
                raise RuntimeError(f"compiling the FMU ({platform}) failed or warned:\n{' '.join(cmd)}\n{out}{err}")
        tmp_fmu = root / f"{ident}.fmu"
        with zipfile.ZipFile(tmp_fmu, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.write(root / "modelDescription.xml", "modelDescription.xml")
            if fmi_version == 3:
                zf.write(root / TERMINALS_FILE, TERMINALS_FILE)
            for platform in platforms:
                zf.write(root / binary_path(fmi_version, ident, platform), binary_path(fmi_version, ident, platform))
            for f in sorted(src_dir.iterdir()):
                zf.write(f, f"sources/{f.name}")
        # a finished FMU replaces the old one, or nothing does (copied, not copyfile'd: a FIFO is written too)
        with atomic_open(fmu_path, "wb") as fh, open(tmp_fmu, "rb") as made:
            shutil.copyfileobj(made, fh)
    return fmu_path
