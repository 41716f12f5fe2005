"""Build the gyrosim FMU: FMI 2.0 / 3.0 co-simulation and model exchange, native code from the engine's C sources.

One FMU kind, offering co-simulation, model exchange or both (``fmi_type``; both interfaces in one binary, as the
Modelica Reference FMUs do). Its binary is the C engine (``core/engine/``: the same sources and floating-point flags
as the Python extension, so an FMU run and ``Model.step`` agree to the bit) plus the FMI glue in ``c/`` (variables,
validation, time, saved state; no physics). No Python on the host. The FMU carries its sources (FMI 2.0
``SourceFiles``, FMI 3.0 ``sources/buildDescription.xml``), from which it rebuilds to the same bits.

Variables come from :func:`gyrosim.model.variables_for`; a multi-body scene exports every body, its variables
named ``<body>.<name>`` (``fast.q_w``), with ``integrator`` and ``max_step`` shared by all bodies. Model exchange
adds the state derivatives ``der(q_w)`` ... ``der(omega_z)`` (``der(fast.q_w)``), local variables after all the
others (the value references of the co-simulation variables do not change): the continuous states are q and omega of
every body, 7 per body, and their derivatives the engine's right-hand side (``gs_derivatives``).

A tree scene (bodies joined by joints, ``Scene.kernel``) builds from the engine's tree (``tree.c``, ``rk.c``) and
one generic glue, ``c/gyrosim_tree_model.c``, chosen at compile time by ``GS_TREE`` in the generated configuration;
its variables are :func:`gyrosim.kernel_tree.tree_variables` and the configuration carries the scene as a table
(:mod:`gyrosim.fmu.tree_fmu`).
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
import uuid
import xml.etree.ElementTree as ET
import zipfile
from importlib import resources
from pathlib import Path

from .._atomic import atomic_open
from ..errors import ConfigError
from ..model import variables_for
from ..scene import INTEGRATORS, TREE_INTEGRATORS, Scene, load_scene

__all__ = ["build_fmu", "model_identifier", "fmi_include_dir", "compile_command", "binary_path", "C_FLAGS",
           "DEFAULT_OUTPUT", "WINDOWS_CC", "WINDOWS_C_FLAGS", "windows_compiler", "PLATFORMS", "engine_sources",
           "SCENE_VARIABLES", "FMI_TYPES", "STATES", "ME_NORM_TOL"]

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

#: The one-body FMU's engine files: the one-body engine, and the tree engine's complex step (tree_cs.c, which
#: #includes tree.c; tree.c and rk.c compiled too) for the directional derivatives.
_ENGINE = ("gyrosim_engine.h", "gyrosim_ode.h", "gyrosim_tree.h", "rk_tables.h", "rk_driver.h", "exact_fast.h",
           "body_dynamics.h", "angles.h", "monitor.h", "splitting.h", "outputs.h", "exact_steps.h", "block.h",
           "engine.c", "exact.c", "rk.c", "tree.c", "tree_cs.c", "cflags.txt")
_GLUE = ("gyrosim_glue_api.h", "gyrosim_glue_common.h", "gyrosim_model.h", "gyrosim_model.c")
#: Scene-wide variables (not per body) of a multi-body FMU.
SCENE_VARIABLES = ("integrator", "max_step", "max_drift")
_KINDS = {"I1": "GS_V_I1", "I2": "GS_V_I2", "I3": "GS_V_I3", "mass": "GS_V_MASS", "cm_distance": "GS_V_CM",
          "g": "GS_V_G", "damping": "GS_V_DAMPING", "integrator": "GS_V_INTEGRATOR", "max_step": "GS_V_MAX_STEP",
          "max_drift": "GS_V_MAX_DRIFT",
          "q_w": "GS_V_QW", "q_x": "GS_V_QX", "q_y": "GS_V_QY", "q_z": "GS_V_QZ", "omega_x": "GS_V_OX",
          "omega_y": "GS_V_OY", "omega_z": "GS_V_OZ", "tau_x": "GS_V_TX", "tau_y": "GS_V_TY", "tau_z": "GS_V_TZ",
          "phi": "GS_V_PHI", "theta": "GS_V_THETA", "psi": "GS_V_PSI", "L_x": "GS_V_LX", "L_y": "GS_V_LY",
          "L_z": "GS_V_LZ", "energy": "GS_V_ENERGY",
          "energy_error": "GS_V_ENERGY_ERROR"}
#: Derived outputs: computed at initialisation (initial="calculated"), not settable.
_DERIVED = ("phi", "theta", "psi", "L_x", "L_y", "L_z", "energy", "energy_error")
_UNITS = {  # unit -> SI base-unit exponents
    "kg.m2": {"kg": 1, "m": 2}, "kg": {"kg": 1}, "m": {"m": 1}, "m/s2": {"m": 1, "s": -2},
    "N.m.s": {"kg": 1, "m": 2, "s": -1}, "s": {"s": 1}, "1": {}, "rad/s": {"rad": 1, "s": -1},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "rad": {"rad": 1}, "kg.m2/s": {"kg": 1, "m": 2, "s": -1},
    "J": {"kg": 1, "m": 2, "s": -2}, "1/s": {"s": -1}, "rad/s2": {"rad": 1, "s": -2},
    # tree scenes
    "N.m/rad": {"kg": 1, "m": 2, "s": -2, "rad": -1}, "N.m.s/rad": {"kg": 1, "m": 2, "s": -1, "rad": -1},
    "m/s": {"m": 1, "s": -1}, "W": {"kg": 1, "m": 2, "s": -3},
}
_TOKEN = "@INSTANTIATION_TOKEN@"
#: ``fmi_type`` values: co-simulation, model exchange, or both interfaces in one FMU.
FMI_TYPES = ("cs", "me", "both")
#: The continuous states of each body (model exchange), in the order of the state vector.
STATES = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")
_DER_KINDS = ("GS_V_DQW", "GS_V_DQX", "GS_V_DQY", "GS_V_DQZ", "GS_V_DOX", "GS_V_DOY", "GS_V_DOZ")
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


def engine_sources(tree: bool = False) -> dict[str, str]:
    """The C sources an FMU is compiled from, ``{file name: text}`` (engine, then glue; no generated config);
    ``tree``: those of a tree scene's FMU (the engine's tree and the generic tree glue)."""
    from .tree_fmu import TREE_ENGINE, TREE_GLUE

    eng = resources.files("gyrosim.core").joinpath("engine")
    glue = resources.files(__package__).joinpath("c")
    out = {name: eng.joinpath(name).read_text() for name in (TREE_ENGINE if tree else _ENGINE)}
    out.update({name: glue.joinpath(name).read_text() for name in (TREE_GLUE if tree else _GLUE)})
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


def fmu_variables(sc: Scene) -> list[tuple[str, int, object]]:
    """``(name, body, Variable)`` in value-reference order (from 1): scene-wide variables once, the rest per body
    (named ``<body>.<name>`` when the scene has several bodies). ``body`` is -1 for scene-wide variables."""
    n = len(sc.bodies)
    rows = []
    base = variables_for(sc, 0)
    if n == 1:
        return [(name, 0, v) for name, v in base.items()]
    for name in SCENE_VARIABLES:
        rows.append((name, -1, base[name]))
    for b, body in enumerate(sc.bodies):
        for name, v in variables_for(sc, b).items():
            if name not in SCENE_VARIABLES:
                rows.append((f"{body.name}.{name}", b, v))
    return rows


def derivative_rows(sc: Scene, rows) -> list[tuple[str, int, int, int]]:
    """Model exchange: ``(name, body, state index, kind)`` of every state derivative, body by body in the order of
    :data:`STATES`; ``state index`` is the 0-based position of the state in ``rows`` (``der(q_w)``,
    ``der(fast.q_w)``)."""
    index = {name: i for i, (name, _, _) in enumerate(rows)}
    out = []
    for b, body in enumerate(sc.bodies):
        for k, st in enumerate(STATES):
            name = st if len(sc.bodies) == 1 else f"{body.name}.{st}"
            out.append((f"der({name})", b, index[name], k))
    return out


def _omega_nominal(body) -> float:
    """The nominal value of a body's omega states: its largest start rate, at least 1 rad/s."""
    return max(1.0, *(abs(float(w)) for w in body.omega0))


def _config_header(sc: Scene, rows, ident: str, token: str, fmi_version: int, integrator: str,
                   fmi_type: str = "cs") -> str:
    # FMI 3.0 has the independent variable time at value reference 0; FMI 2.0 leaves 0 unused
    kinds = ["GS_V_TIME" if fmi_version == 3 else "GS_V_NONE"] + [_KINDS[v.name] for _, _, v in rows]
    bodies = ["0"] + [str(max(b, 0)) for _, b, _ in rows]
    if fmi_type != "cs":
        for _, b, _, k in derivative_rows(sc, rows):
            kinds.append(_DER_KINDS[k])
            bodies.append(str(b))
    g = sc.g if sc.gravity else 0.0  # Model: g of a scene without gravity is 0 (no potential energy term)
    starts = []
    for body in sc.bodies:
        vals = [*body.moments, body.mass, body.cm_distance, g, body.damping, *body.q0, *body.omega0]
        starts.append("{" + ", ".join(_hexf(v) for v in vals) + "}")
    lines = [
        "/* Generated by gyrosim.fmu.build: the scene's variables, value references and start values. */",
        "#ifndef GYROSIM_CONFIG_H", "#define GYROSIM_CONFIG_H", "",
        f"#define FMI_VERSION {fmi_version}",
        f"#define MODEL_IDENTIFIER {ident}",
        f'#define MODEL_IDENTIFIER_STRING "{ident}"',
        f'#define INSTANTIATION_TOKEN "{token}"',
        f"#define GS_SCENE_NAME {_c_string(sc.name)}", "",
        f"#define GS_N_BODIES {len(sc.bodies)}",
        f"#define GS_FLAGS {sc.flags}   /* GRAVITY=1, DAMPING=2, TORQUE=4 */",
        f"#define GS_HAS_GRAVITY {int(sc.gravity)}",
        f"#define GS_HAS_CS {int(fmi_type in ('cs', 'both'))}   /* the interfaces: --fmi-type {fmi_type} */",
        f"#define GS_HAS_ME {int(fmi_type in ('me', 'both'))}",
        "#define GS_OMEGA_NOMINALS {" + ", ".join(_hexf(_omega_nominal(b)) for b in sc.bodies) + "}", "",
        "/* value reference -> variable kind and body (index = value reference) */",
        "#define GS_VR_KINDS {" + ", ".join(kinds) + "}",
        "#define GS_VR_BODIES {" + ", ".join(bodies) + "}",
        "#define GS_BODY_NAMES {" + ", ".join(_c_string(b.name) for b in sc.bodies) + "}", "",
        f"#define GS_START_INTEGRATOR_CODE {_engine_methods().index(integrator)}   /* {integrator} */",
        f"#define GS_START_MAX_STEP {_hexf(sc.max_step)}   /* {_fmt(sc.max_step)} */",
        f"#define GS_START_MAX_DRIFT {_hexf(sc.max_drift)}   /* {_fmt(sc.max_drift)} */",
        f"#define GS_START_TOLERANCE {_hexf(sc.tolerance)}   /* {_fmt(sc.tolerance)} */",
        "/* per body: I1, I2, I3, mass, cm_distance, g, damping, q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z */",
        "#define GS_START_BODIES {" + ", \\\n    ".join(starts) + "}",
        "", "#endif", "",
    ]
    return "\n".join(lines)


def _variable_description(name: str, v, sc: Scene) -> str:
    if name == "integrator":
        return v.description
    return v.description


_ME_NOTE = ("Model exchange: the continuous states are q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z of every body, "
            "their derivatives the engine's right-hand side; the host's solver integrates them (integrator, max_step, "
            "max_drift and the tolerance act in co-simulation only). |q| is a first integral of the flow, so it "
            "drifts by the solver's error only: when a completed integrator step finds | |q| - 1 | > "
            f"{ME_NORM_TOL:g}, the FMU asks for a step event and renormalises q in the event update "
            "(valuesOfContinuousStatesChanged); the derived outputs use q normalised. No event indicators.")


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
                     units) -> ET.Element:
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
        root.set("numberOfEventIndicators", "0")
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
                     "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "false",
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
                       "providesDirectionalDerivatives": "true", "providesAdjointDerivatives": "false",
                       "hasEventMode": "false", "canReturnEarlyAfterIntermediateUpdate": "false",
                       "providesIntermediateUpdate": "false"})
    for k, v in common.items():
        cs.set(k, v)
    if fmi_version == 2:
        source_files(cs, sources)
    units = sorted(set(units) | {"s"})
    ud = ET.SubElement(root, "UnitDefinitions")
    for u in units:
        ue = ET.SubElement(ud, "Unit", name=u)
        ET.SubElement(ue, "BaseUnit", {k: str(e) for k, e in _UNITS[u].items()})
    lc = ET.SubElement(root, "LogCategories")
    for name, d in _LOG_CATEGORIES:
        ET.SubElement(lc, "Category", name=name, description=d)
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=_fmt(sc.stop_time),
                  tolerance=_fmt(sc.tolerance), stepSize=_fmt(sc.output_interval))
    return root


def _model_description(sc: Scene, rows, ident, token, fmi_version, integrator, sources, fmi_type="cs",
                       platforms=("linux",)) -> str:
    has_me = fmi_type in ("me", "both")
    integ = [i if i != "exact" or sc.exact_start() is None else "exact (a torque-free body or a Lagrange top only)"
             for i in INTEGRATORS]
    kind = {"cs": "co-simulation", "me": "model exchange", "both": "co-simulation and model exchange"}[fmi_type]
    desc = (f"gyrosim {sc.name if sc.name != 'full' else 'rigid body (full model)'}: "
            f"{sc.description or 'rigid body'}. Native FMU (the gyrosim C engine, no Python), {kind}; "
            f"{len(sc.bodies)} bod{'y' if len(sc.bodies) == 1 else 'ies'}; integrators " + ", ".join(integ) + "."
            + (" " + _ME_NOTE if has_me else "") + " " + _platforms_note(platforms))
    ders = derivative_rows(sc, rows) if has_me else []
    is_state = {i for _, _, i, _ in ders}
    units = {v.unit for _, _, v in rows if v.unit} | ({"1/s", "rad/s2"} if has_me else set())
    root = description_head(sc, ident, token, fmi_version, desc, sources, fmi_type, units)
    mv = ET.SubElement(root, "ModelVariables")
    if fmi_version == 3:
        ET.SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", unit="s", description="simulation time")
    outputs, initial_unknowns = [], []
    b_of = [b for _, b, _ in rows]
    for i, (name, _, v) in enumerate(rows):
        vr = i + 1
        index = i + 1  # 1-based index in ModelVariables (FMI 2.0)
        attrs = {"name": name, "valueReference": str(vr), "causality": v.causality,
                 "variability": v.variability, "description": _variable_description(v.name, v, sc)}
        start = None
        if v.causality == "output":
            outputs.append((index, vr))
            if v.name in _DERIVED:
                attrs["initial"] = "calculated"
                initial_unknowns.append((index, vr))
            else:
                attrs["initial"] = "exact"
                start = v.start
        elif v.causality == "parameter":
            attrs["initial"] = "exact"
            start = integrator if v.name == "integrator" else v.start
        else:
            start = v.start
        nominal = None
        if i in is_state and v.name.startswith("omega"):
            nominal = _fmt(_omega_nominal(sc.bodies[max(b_of[i], 0)]))
        if fmi_version == 2:
            sv = ET.SubElement(mv, "ScalarVariable", attrs)
            t = ET.SubElement(sv, "Real" if v.type == "Real" else "String")
            if start is not None:
                t.set("start", start if isinstance(start, str) else _fmt(start))
            if v.type == "Real" and v.unit:
                t.set("unit", v.unit)
            if v.type == "Real":
                range_attributes(t.attrib, v)
            if nominal is not None:
                t.set("nominal", nominal)
        else:
            if v.type == "Real":
                if start is not None:
                    attrs["start"] = _fmt(start)
                if v.unit:
                    attrs["unit"] = v.unit
                range_attributes(attrs, v)
                if nominal is not None:
                    attrs["nominal"] = nominal
                ET.SubElement(mv, "Float64", attrs)
            else:
                se = ET.SubElement(mv, "String", attrs)
                ET.SubElement(se, "Start", value=str(start))
    derivatives = []
    for j, (name, _, si, k) in enumerate(ders):
        vr = index = len(rows) + 1 + j
        derivatives.append((index, vr))
        initial_unknowns.append((index, vr))   # initial="calculated" (a local continuous variable's default)
        unit = "1/s" if k < 4 else "rad/s2"
        what = f"derivative of {rows[si][0]}" + (" (model exchange: dq/dt = q * (0, omega) / 2)" if k < 4 else
                                                  " (model exchange: Euler's equations with the scene's torques)")
        attrs = {"name": name, "valueReference": str(vr), "causality": "local", "variability": "continuous",
                 "description": what}
        if fmi_version == 2:
            sv = ET.SubElement(mv, "ScalarVariable", attrs)
            ET.SubElement(sv, "Real", unit=unit, derivative=str(si + 1))
        else:
            attrs.update(unit=unit, derivative=str(si + 1))
            ET.SubElement(mv, "Float64", attrs)
    model_structure(root, fmi_version, [vr for _, vr in outputs], [vr for _, vr in derivatives],
                    [vr for _, vr in initial_unknowns], one_body_dependencies(sc, rows, has_me))
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def one_body_dependencies(sc: Scene, rows, has_me: bool) -> dict[int, list[int]]:
    """The ModelStructure's dependencies of a one-body scene's FMU: ``{value reference of an output or a state
    derivative: value references of the knowns it depends on}`` (the knowns of the directional derivatives: the
    continuous states and the inputs). Bodies are independent. Co-simulation only: no output depends on an input at
    an instant (the outputs are the state and functions of it), so every list is empty. Model exchange: q_*, omega_*
    on themselves; phi, theta, psi on q; L, energy, energy_error on q and omega; der(q_*) on q and omega; der(omega_*)
    on omega, the body's inputs and, with gravity, q (the gravity torque; domega/dt sees q normalised, so all four)."""
    vr_of = {(b, v.name): i + 1 for i, (_, b, v) in enumerate(rows)}
    out: dict[int, list[int]] = {}
    for i, (_, _, v) in enumerate(rows):
        if v.causality == "output":
            out[i + 1] = []
    if not has_me:
        return out
    gravity = bool(sc.flags & 1)
    for b in range(len(sc.bodies)):
        q = [vr_of[(b, n)] for n in STATES[:4]]
        w = [vr_of[(b, n)] for n in STATES[4:]]
        tau = [vr_of[(b, n)] for n in ("tau_x", "tau_y", "tau_z") if (b, n) in vr_of]
        for (bb, name), vr in vr_of.items():
            if bb != b or vr not in out:
                continue
            out[vr] = [vr] if name in STATES else q if name in ("phi", "theta", "psi") else q + w
        for j, (_, db, _, k) in enumerate(derivative_rows(sc, rows)):
            if db == b:
                out[len(rows) + 1 + j] = q + w if k < 4 else (q if gravity else []) + w + tau
    return {k: sorted(v) for k, v in out.items()}


def model_structure(root: ET.Element, fmi_version: int, outputs, derivatives, initial_unknowns, deps) -> None:
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
                    platform: str = "linux", *, tree: bool = False) -> list[str]:
    """The compiler command that builds the FMU's shared library from ``src_dir`` (the FMU's sources);
    ``platform`` "windows" cross-compiles the DLL with MinGW-w64 (``cc`` default :data:`WINDOWS_CC`); ``tree``:
    the FMU of a tree scene (the engine's tree and the generic tree glue)."""
    if platform == "windows":
        cc, flags = cc or WINDOWS_CC, WINDOWS_C_FLAGS
    else:
        cc, flags = cc or os.environ.get("CC", "gcc"), C_FLAGS
    if tree:
        srcs = ["engine.c", "exact.c", "rk.c", "tree.c", "tree_cs.c", "gyrosim_tree_model.c",
                f"fmi{fmi_version}Functions.c"]
    else:
        srcs = ["engine.c", "exact.c", "rk.c", "tree.c", "tree_cs.c", "gyrosim_model.c", f"fmi{fmi_version}Functions.c"]
    return [cc, *flags, "-shared", f"-I{src_dir}", f"-I{fmi_include_dir()}",
            *[str(src_dir / s) for s in srcs], "-o", str(out), "-Wl,--no-undefined", "-lm"]


#: The engine's translation units: the same text in every FMU, so compiled once per compiler, flags and text and kept
#: (:func:`_engine_objects`); an FMU build then compiles only its glue.
ENGINE_UNITS = ("engine.c", "exact.c", "rk.c", "tree.c", "tree_cs.c")
#: The headers the engine's units include (and nothing else: the glue's headers and the generated configuration
#: are not the engine's).
ENGINE_HEADERS = ("gyrosim_engine.h", "gyrosim_ode.h", "gyrosim_tree.h", "rk_tables.h", "rk_driver.h", "exact_fast.h",
                  "body_dynamics.h", "angles.h", "monitor.h", "splitting.h", "outputs.h", "exact_steps.h", "block.h")


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
        part = obj.with_name(f".{obj.name}.{os.getpid()}.{len(jobs)}.tmp")
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
        (``RigidBody.fmu``) with every variable of fmu/README.md. Every body of the scene is exported. A tree
        scene (bodies joined by joints) exports :func:`gyrosim.kernel_tree.tree_variables` through the generic tree
        glue (:mod:`gyrosim.fmu.tree_fmu`); its integrators are euler, rk4, adaptive and dop853.
    fmi_version : {2, 3}
    output_dir : path
        Created if missing.
    fmi_type : {"cs", "me", "both"}
        The interfaces: co-simulation (the engine's integrators step the model), model exchange (the host's
        solver integrates q and omega, 7 continuous states per body) or both in one FMU. ``gyrosim fmu build``
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
    if (sc.kernel == "tree"):
        if integrator not in TREE_INTEGRATORS:
            raise ConfigError("integrator", integrator, "one of " + ", ".join(TREE_INTEGRATORS) + " (a tree of "
                              "bodies is integrated by the tree engine)")
    elif integrator not in INTEGRATORS:
        raise ConfigError("integrator", integrator, "one of " + ", ".join(INTEGRATORS))
    elif integrator == "exact" and sc.exact_start() is not None:
        raise ConfigError("integrator", integrator, "a general integrator: 'exact' solves a torque-free body or a "
                          f"Lagrange top only, and scene {sc.name!r} starts with {sc.exact_start()}")
    ident = model_identifier(scene)
    win_cc = windows_compiler() if windows is not False else None
    if windows and win_cc is None:
        raise RuntimeError(f"the Windows binary needs the MinGW-w64 cross-compiler {WINDOWS_CC!r} on PATH "
                           "(Debian/Ubuntu: apt-get install gcc-mingw-w64-x86-64)")
    platforms = ("linux", "windows") if win_cc else ("linux",)
    texts = engine_sources(tree=(sc.kernel == "tree"))
    texts[f"fmi{fmi_version}Functions.c"] = resources.files(__package__).joinpath(
        "c", f"fmi{fmi_version}Functions.c").read_text()
    sources = [*texts, "gyrosim_config.h"]
    # a deterministic token: a hash of everything the FMU is made of (with a placeholder for the token itself)
    if (sc.kernel == "tree"):   # the generic tree glue and the scene's variable table (tree_fmu)
        from .tree_fmu import tree_config_header, tree_me_rows, tree_model_description, tree_rows

        rows = tree_rows(sc)
        me_rows = tree_me_rows(sc, rows)
        md = tree_model_description(sc, rows, me_rows, ident, _TOKEN, fmi_version, integrator, sources, fmi_type,
                                    platforms)
        config = tree_config_header(sc, rows, me_rows, ident, _TOKEN, fmi_version, integrator, fmi_type)
    else:
        rows = fmu_variables(sc)
        md = _model_description(sc, rows, ident, _TOKEN, fmi_version, integrator, sources, fmi_type, platforms)
        config = _config_header(sc, rows, ident, _TOKEN, fmi_version, integrator, fmi_type)
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
        # the engine's objects: compiled once per compiler, flags and text (a cache shared by builds), side by side
        # for the platforms; then each platform's library from them and the glue
        plans, pending = [], []
        for platform in platforms:
            so = root / binary_path(fmi_version, ident, platform)
            so.parent.mkdir(parents=True)
            tree = sc.kernel == "tree"
            cmd = (compile_command(src_dir, so, fmi_version, win_cc, "windows", tree=tree)
                   if platform == "windows" else compile_command(src_dir, so, fmi_version, cc, tree=tree))
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
            for platform in platforms:
                zf.write(root / binary_path(fmi_version, ident, platform), binary_path(fmi_version, ident, platform))
            for f in sorted(src_dir.iterdir()):
                zf.write(f, f"sources/{f.name}")
        # a finished FMU replaces the old one, or nothing does (copied, not copyfile'd: a FIFO is written too)
        with atomic_open(fmu_path, "wb") as fh, open(tmp_fmu, "rb") as made:
            shutil.copyfileobj(made, fh)
    return fmu_path
