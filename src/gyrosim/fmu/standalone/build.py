"""Build the standalone FMU: native code compiled with the system C compiler, no Python inside.

The variables, units and start values come from :func:`gyrosim.model.variables_for` (the same source as the
Python-backed FMU); the physics is the hand-written C mirror of :mod:`gyrosim.core.kernels` in ``c/``, checked
against :class:`gyrosim.model.Model` to 1e-12 by ``tests/standalone``. The FMU also carries its C sources (FMI 2.0
``SourceFiles``, FMI 3.0 ``sources/buildDescription.xml``), so other platforms can compile it.
"""

from __future__ import annotations

import hashlib
import math
import os
import shutil
import subprocess
import tempfile
import uuid
import xml.etree.ElementTree as ET
import zipfile
from importlib import resources
from pathlib import Path

from ...core import kernels
from ...errors import ConfigError
from ...model import variables_for
from ...scene import Scene, load_scene

__all__ = ["build_standalone", "model_identifier", "INTEGRATORS", "fmi_include_dir", "compile_command",
           "binary_path", "C_FLAGS"]

#: Integrators of the standalone FMU (``adaptive`` and ``exact`` need the Python-backed FMU).
INTEGRATORS = ("euler", "rk4", "splitting", "splitting4")
_CODES = {"euler": 0, "rk4": 1, "splitting": 2, "splitting4": 3}
assert all(kernels.METHOD_CODES[k] == v for k, v in _CODES.items())

#: Compiler flags: -ffp-contract=off keeps every product and sum a separate IEEE operation, as numpy and numba
#: do, which is what lets the C kernel reproduce the Python kernel to the bit.
C_FLAGS = ("-std=c99", "-O2", "-Wall", "-Wextra", "-ffp-contract=off", "-fPIC", "-fvisibility=hidden")

_SOURCES = ("gyrosim_kernel.h", "gyrosim_kernel.c", "gyrosim_model.h", "gyrosim_model.c")
_KINDS = {"I1": "GS_V_I1", "I2": "GS_V_I2", "I3": "GS_V_I3", "mass": "GS_V_MASS", "cm_distance": "GS_V_CM",
          "g": "GS_V_G", "damping": "GS_V_DAMPING", "integrator": "GS_V_INTEGRATOR", "max_step": "GS_V_MAX_STEP",
          "q_w": "GS_V_QW", "q_x": "GS_V_QX", "q_y": "GS_V_QY", "q_z": "GS_V_QZ", "omega_x": "GS_V_OX",
          "omega_y": "GS_V_OY", "omega_z": "GS_V_OZ", "tau_x": "GS_V_TX", "tau_y": "GS_V_TY", "tau_z": "GS_V_TZ",
          "phi": "GS_V_PHI", "theta": "GS_V_THETA", "psi": "GS_V_PSI", "L_x": "GS_V_LX", "L_y": "GS_V_LY",
          "L_z": "GS_V_LZ", "energy": "GS_V_ENERGY"}
#: Derived outputs: computed at initialisation (initial="calculated"), not settable.
_DERIVED = ("phi", "theta", "psi", "L_x", "L_y", "L_z", "energy")
_UNITS = {  # unit -> SI base-unit exponents
    "kg.m2": {"kg": 1, "m": 2}, "kg": {"kg": 1}, "m": {"m": 1}, "m/s2": {"m": 1, "s": -2},
    "N.m.s": {"kg": 1, "m": 2, "s": -1}, "s": {"s": 1}, "1": {}, "rad/s": {"rad": 1, "s": -1},
    "N.m": {"kg": 1, "m": 2, "s": -2}, "rad": {"rad": 1}, "kg.m2/s": {"kg": 1, "m": 2, "s": -1},
    "J": {"kg": 1, "m": 2, "s": -2},
}
_TOKEN = "@INSTANTIATION_TOKEN@"
_LOG_CATEGORIES = (("logStatusWarning", "Log messages with status Warning (this FMU has none)."),
                   ("logStatusError", "Log messages with status Error: illegal calls, invalid values, failed steps."),
                   ("logStatusFatal", "Log messages with status Fatal (this FMU has none)."),
                   ("logEvents", "Log instantiation."))


def _c_source_dir():
    return resources.files(__package__).joinpath("c")


def fmi_include_dir() -> Path:
    """The FMI 2.0 / 3.0 C headers that FMPy ships (``fmpy/c-code``)."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def model_identifier(scene: str | Path | Scene | None = None) -> str:
    """``RigidBody`` for the full model, else the scene name in CamelCase (``heavy_top`` -> ``HeavyTop``)."""
    sc = load_scene(scene)
    if scene is None or sc.name == "full":
        return "RigidBody"
    parts = [p for p in sc.name.replace("-", "_").split("_") if p]
    ident = "".join(p[:1].upper() + p[1:] for p in parts)
    return ident if ident[:1].isalpha() else "Scene" + ident


def binary_path(fmi_version: int, identifier: str) -> str:
    """Path of the shared library inside the FMU (Linux x86-64)."""
    return f"binaries/{'linux64' if fmi_version == 2 else 'x86_64-linux'}/{identifier}.so"


def _hexf(x: float) -> str:
    """A C99 hexadecimal floating literal: the exact double, whatever the compiler's decimal rounding."""
    x = float(x)
    if not math.isfinite(x):
        raise ConfigError("start value", x, "a finite number")
    return x.hex()


def _fmt(x) -> str:
    return repr(float(x))


def _config_header(sc: Scene, variables, vrs: dict[str, int], ident: str, token: str, fmi_version: int,
                   integrator: str) -> str:
    b = sc.bodies[0]
    # FMI 3.0 has the independent variable time at value reference 0; FMI 2.0 leaves 0 unused
    kinds = ["GS_V_TIME" if fmi_version == 3 else "GS_V_NONE"] + [_KINDS[n] for n in variables]
    assert [vrs[n] for n in variables] == list(range(1, len(variables) + 1))
    start = {
        "I1": b.moments[0], "I2": b.moments[1], "I3": b.moments[2], "MASS": b.mass, "CM_DISTANCE": b.cm_distance,
        # Model: g of a scene without gravity is 0 (no potential energy term)
        "G": sc.g if sc.gravity else 0.0, "DAMPING": b.damping, "MAX_STEP": sc.max_step,
        "TOLERANCE": sc.tolerance, "Q_W": b.q0[0], "Q_X": b.q0[1], "Q_Y": b.q0[2], "Q_Z": b.q0[3],
        "OMEGA_X": b.omega0[0], "OMEGA_Y": b.omega0[1], "OMEGA_Z": b.omega0[2],
    }
    flags = sc.flags
    lines = [
        "/* Generated by gyrosim.fmu.standalone.build: the scene's variables, value references and start values. */",
        "#ifndef GYROSIM_CONFIG_H", "#define GYROSIM_CONFIG_H", "",
        f"#define FMI_VERSION {fmi_version}",
        f"#define MODEL_IDENTIFIER {ident}",
        f'#define MODEL_IDENTIFIER_STRING "{ident}"',
        f'#define INSTANTIATION_TOKEN "{token}"',
        f'#define GS_SCENE_NAME "{sc.name}"', "",
        f"#define GS_FLAGS {flags}   /* GRAVITY={kernels.GRAVITY}, DAMPING={kernels.DAMPING}, "
        f"TORQUE={kernels.TORQUE} */",
        f"#define GS_HAS_GRAVITY {int(sc.gravity)}",
        f"#define GS_HAS_DAMPING {int(sc.damping)}",
        f"#define GS_HAS_TORQUE {int(sc.torque)}", "",
        "/* value reference -> variable (index = value reference) */",
        "#define GS_VR_KINDS {" + ", ".join(kinds) + "}", "",
        f"#define GS_START_INTEGRATOR_CODE {_CODES[integrator]}   /* {integrator} */",
    ]
    for k, v in start.items():
        lines.append(f"#define GS_START_{k} {_hexf(v)}   /* {_fmt(v)} */")
    lines += [
        "",
        "/* constants of gyrosim.core.kernels, bit for bit */",
        f"#define GS_PI {_hexf(math.pi)}",
        f"#define GS_TWO_PI {_hexf(kernels.TWO_PI)}",
        f"#define GS_Y0 {_hexf(kernels._Y0)}",
        f"#define GS_Y1 {_hexf(kernels._Y1)}",
        "", "#endif", "",
    ]
    return "\n".join(lines)


def _indent(elem: ET.Element) -> None:
    ET.indent(elem, space="  ")


def _variable_description(name: str, v) -> str:
    if name == "integrator":
        return ("integrator: " + ", ".join(INTEGRATORS) + " (standalone FMU; adaptive and exact need the "
                "Python-backed FMU)")
    return v.description


def _model_description(sc: Scene, variables, vrs, ident, token, fmi_version, integrator, sources) -> str:
    from ... import __version__

    desc = (f"gyrosim {sc.name if sc.name != 'full' else 'rigid body (full model)'}: "
            f"{sc.description or 'rigid body'}. Standalone native FMU (C, no Python); integrators "
            + ", ".join(INTEGRATORS) + " (adaptive and exact only in the Python-backed FMU).")
    root = ET.Element("fmiModelDescription")
    root.set("fmiVersion", "2.0" if fmi_version == 2 else "3.0")
    root.set("modelName", ident)
    root.set("guid" if fmi_version == 2 else "instantiationToken", token)
    root.set("description", desc)
    root.set("generationTool", f"gyrosim {__version__} (gyrosim.fmu.standalone)")
    root.set("variableNamingConvention", "flat")
    if fmi_version == 2:
        root.set("numberOfEventIndicators", "0")
    cs = ET.SubElement(root, "CoSimulation")
    cs.set("modelIdentifier", ident)
    common = {"needsExecutionTool": "false", "canHandleVariableCommunicationStepSize": "true",
              "canBeInstantiatedOnlyOncePerProcess": "false", "maxOutputDerivativeOrder": "0"}
    if fmi_version == 2:
        common.update({"canInterpolateInputs": "false", "canRunAsynchronuously": "false",
                       "canNotUseMemoryManagementFunctions": "true", "canGetAndSetFMUstate": "true",
                       "canSerializeFMUstate": "true", "providesDirectionalDerivative": "false"})
    else:
        common.update({"canGetAndSetFMUState": "true", "canSerializeFMUState": "true",
                       "providesDirectionalDerivatives": "false", "providesAdjointDerivatives": "false",
                       "hasEventMode": "false", "canReturnEarlyAfterIntermediateUpdate": "false",
                       "providesIntermediateUpdate": "false"})
    for k, v in common.items():
        cs.set(k, v)
    if fmi_version == 2:
        sf = ET.SubElement(cs, "SourceFiles")
        for s in sources:
            if s.endswith(".c"):
                ET.SubElement(sf, "File", name=s)
    units = sorted({v.unit for v in variables.values() if v.unit} | {"s"})
    ud = ET.SubElement(root, "UnitDefinitions")
    for u in units:
        ue = ET.SubElement(ud, "Unit", name=u)
        ET.SubElement(ue, "BaseUnit", {k: str(e) for k, e in _UNITS[u].items()})
    lc = ET.SubElement(root, "LogCategories")
    for name, d in _LOG_CATEGORIES:
        ET.SubElement(lc, "Category", name=name, description=d)
    ET.SubElement(root, "DefaultExperiment", startTime="0", stopTime=_fmt(sc.stop_time),
                  tolerance=_fmt(sc.tolerance), stepSize=_fmt(sc.output_interval))
    mv = ET.SubElement(root, "ModelVariables")
    if fmi_version == 3:  # as the Python-backed FMU: time only in FMI 3.0
        ET.SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", unit="s", description="simulation time")
    outputs, initial_unknowns = [], []
    for i, (name, v) in enumerate(variables.items()):
        index = i + 1  # 1-based index in ModelVariables (FMI 2.0)
        attrs = {"name": name, "valueReference": str(vrs[name]), "causality": v.causality,
                 "variability": v.variability, "description": _variable_description(name, v)}
        start = None
        if v.causality == "output":
            outputs.append((index, vrs[name]))
            if name in _DERIVED:
                attrs["initial"] = "calculated"
                initial_unknowns.append((index, vrs[name]))
            else:
                attrs["initial"] = "exact"
                start = v.start
        elif v.causality == "parameter":
            attrs["initial"] = "exact"
            start = integrator if name == "integrator" else v.start
        else:
            start = v.start
        if fmi_version == 2:
            sv = ET.SubElement(mv, "ScalarVariable", attrs)
            t = ET.SubElement(sv, "Real" if v.type == "Real" else "String")
            if start is not None:
                t.set("start", start if isinstance(start, str) else _fmt(start))
            if v.type == "Real" and v.unit:
                t.set("unit", v.unit)
        else:
            if v.type == "Real":
                if start is not None:
                    attrs["start"] = _fmt(start)
                if v.unit:
                    attrs["unit"] = v.unit
                ET.SubElement(mv, "Float64", attrs)
            else:
                se = ET.SubElement(mv, "String", attrs)
                ET.SubElement(se, "Start", value=str(start))
    ms = ET.SubElement(root, "ModelStructure")
    if fmi_version == 2:
        oe = ET.SubElement(ms, "Outputs")
        for index, _ in outputs:
            ET.SubElement(oe, "Unknown", index=str(index))
        ie = ET.SubElement(ms, "InitialUnknowns")
        for index, _ in initial_unknowns:
            ET.SubElement(ie, "Unknown", index=str(index))
    else:
        for _, vr in outputs:
            ET.SubElement(ms, "Output", valueReference=str(vr))
        for _, vr in initial_unknowns:
            ET.SubElement(ms, "InitialUnknown", valueReference=str(vr))
    _indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def _build_description(ident: str, sources) -> str:
    root = ET.Element("fmiBuildDescription", fmiVersion="3.0")
    bc = ET.SubElement(root, "BuildConfiguration", modelIdentifier=ident,
                       description="C99; compile with -ffp-contract=off (no fused multiply-add) to reproduce "
                                   "the Python model to the bit; link libm")
    sfs = ET.SubElement(bc, "SourceFileSet", language="C99", compilerOptions="-ffp-contract=off")
    for s in sources:
        if s.endswith(".c"):
            ET.SubElement(sfs, "SourceFile", name=s)
    ET.SubElement(bc, "Library", name="m", external="true", description="the C math library (libm)")
    _indent(root)
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"


def compile_command(src_dir: Path, out: Path, fmi_version: int, cc: str | None = None) -> list[str]:
    """The compiler command that builds the FMU's shared library from ``src_dir`` (the FMU's sources)."""
    cc = cc or os.environ.get("CC", "gcc")
    srcs = ["gyrosim_kernel.c", "gyrosim_model.c", f"fmi{fmi_version}Functions.c"]
    return [cc, *C_FLAGS, "-shared", f"-I{src_dir}", f"-I{fmi_include_dir()}",
            *[str(src_dir / s) for s in srcs], "-o", str(out), "-Wl,--no-undefined", "-lm"]


def build_standalone(scene: str | Path | Scene | None = None, fmi_version: int = 2,
                     output_dir: str | Path = Path("fmu/dist"), *, integrator: str | None = None,
                     cc: str | None = None) -> Path:
    """Build ``<output_dir>/<ModelIdentifier>.fmu``: a co-simulation FMU whose binary is native C.

    Parameters
    ----------
    scene : str, Path, Scene or None
        Embedded scene name, TOML path or :class:`~gyrosim.scene.Scene`; ``None`` is the full model
        (``RigidBody.fmu``) with every variable of DESIGN.md section 4. The scene must have one body.
    fmi_version : {2, 3}
    output_dir : path
        Created if missing.
    integrator : str, optional
        Start value of the ``integrator`` parameter (default the scene's); one of :data:`INTEGRATORS`.
    cc : str, optional
        C compiler (default ``$CC`` or ``gcc``).

    Returns
    -------
    Path of the FMU.

    Raises
    ------
    ConfigError
        An unknown FMI version, a scene with several bodies, an integrator the standalone FMU does not have.
    RuntimeError
        The C compiler failed (its output in the message).
    """
    if fmi_version not in (2, 3):
        raise ConfigError("fmi_version", fmi_version, "2 or 3")
    sc = load_scene(scene)
    if len(sc.bodies) != 1:
        raise ConfigError("scene", sc.name, f"a scene with one body: the standalone FMU simulates one body "
                          f"(this scene has {len(sc.bodies)})")
    integrator = sc.integrator if integrator is None else integrator
    if integrator not in INTEGRATORS:
        raise ConfigError("integrator", integrator, "one of " + ", ".join(INTEGRATORS) + " (the standalone FMU; "
                          "'adaptive' and 'exact' need the Python-backed FMU): pass integrator=...")
    ident = model_identifier(scene)
    variables = variables_for(sc)
    vrs = {n: i + 1 for i, n in enumerate(variables)}
    csrc = _c_source_dir()
    texts = {s: csrc.joinpath(s).read_text() for s in (*_SOURCES, f"fmi{fmi_version}Functions.c")}
    sources = [*texts, "gyrosim_config.h"]
    # a deterministic token: a hash of everything the FMU is made of (with a placeholder for the token itself)
    md = _model_description(sc, variables, vrs, ident, _TOKEN, fmi_version, integrator, sources)
    config = _config_header(sc, variables, vrs, ident, _TOKEN, fmi_version, integrator)
    h = hashlib.sha256()
    for part in (md, config, *texts.values()):
        h.update(part.encode())
    token = "{" + str(uuid.UUID(bytes=h.digest()[:16], version=5)) + "}"
    md, config = md.replace(_TOKEN, token), config.replace(_TOKEN, token)
    output_dir = Path(output_dir)
    output_dir.mkdir(parents=True, exist_ok=True)
    fmu_path = output_dir / f"{ident}.fmu"
    with tempfile.TemporaryDirectory(prefix="gyrosim_standalone_") as tmp:
        root = Path(tmp)
        src_dir = root / "sources"
        src_dir.mkdir()
        for name, text in texts.items():
            (src_dir / name).write_text(text)
        (src_dir / "gyrosim_config.h").write_text(config)
        if fmi_version == 3:
            (src_dir / "buildDescription.xml").write_text(_build_description(ident, sources))
        (root / "modelDescription.xml").write_text(md)
        so = root / binary_path(fmi_version, ident)
        so.parent.mkdir(parents=True)
        cmd = compile_command(src_dir, so, fmi_version, cc)
        try:
            r = subprocess.run(cmd, capture_output=True, text=True)
        except FileNotFoundError:
            raise RuntimeError(f"C compiler {cmd[0]!r} not found: the standalone FMU is compiled at build time "
                               "(install gcc, or set CC)") from None
        if r.returncode != 0 or r.stderr.strip():
            raise RuntimeError(f"compiling the standalone FMU failed or warned:\n{' '.join(cmd)}\n{r.stderr}")
        tmp_fmu = root / f"{ident}.fmu"
        with zipfile.ZipFile(tmp_fmu, "w", zipfile.ZIP_DEFLATED) as zf:
            zf.write(root / "modelDescription.xml", "modelDescription.xml")
            zf.write(so, binary_path(fmi_version, ident))
            for f in sorted(src_dir.iterdir()):
                zf.write(f, f"sources/{f.name}")
        shutil.copyfile(tmp_fmu, fmu_path)
    return fmu_path
