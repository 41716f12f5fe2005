"""The binary of the Python-backed gyrosim FMUs: a C bridge from the FMI functions to the model's Python facade.

The bridge (``bridge_c/pybridge.h``, ``bridge_c/fmi2_bridge.c``, ``bridge_c/fmi3_bridge.c``, shipped with gyrosim)
is compiled per FMU with the system C compiler against the FMI headers FMPy ships (``fmpy/c-code``). It runs
the facade (:mod:`gyrosim.fmu.slave`, vendored into the FMU's resources) in the host's own Python interpreter,
looking the Python C API up at run time, so it links against no libpython. It replaced pythonfmu's and
pythonfmu3's export libraries (see docs/fmu.md for why): they turned Python exceptions into ``Fatal``, had no
way to return ``Error``, dropped the FMI 3.0 experiment arguments, and finalised Python from a static destructor
at process exit, which corrupted the heap of hosts that also ran a Zenoh session.

Every FMI function of the version is exported. Those the FMU does not support are generated here from the
header's function types: they log why and return ``Error``; the getters and setters of variable types the FMU
does not have return ``OK`` for zero value references, as the Reference FMUs do.

A plain ``doStep`` takes a fast path: a numba cfunc (:mod:`gyrosim.fmu.fast`) advances the model's state
arrays without the GIL or any Python call (see ``pybridge.h``).
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

__all__ = ["fmi_headers_dir", "function_types", "bridge_source", "compile_bridge", "have_compiler"]

BRIDGE_DIR = Path(__file__).parent / "bridge_c"


def fmi_headers_dir() -> Path:
    """The FMI 2.0 / 3.0 C headers shipped with FMPy (``fmpy/c-code``)."""
    import fmpy

    return Path(fmpy.__file__).parent / "c-code"


def have_compiler() -> str | None:
    """Path of the C compiler (``$CC``, gcc or cc), or None."""
    cc = os.environ.get("CC")
    if cc and shutil.which(cc):
        return shutil.which(cc)
    return shutil.which("gcc") or shutil.which("cc")


def function_types(fmi_version: int, headers: Path | None = None) -> list[tuple[str, str, str, list[str]]]:
    """Parse ``fmiXFunctionTypes.h``: ``[(return type, function name, parameter text, parameter names)]``."""
    headers = headers or fmi_headers_dir()
    text = (headers / f"fmi{fmi_version}FunctionTypes.h").read_text()
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    out = []
    pattern = r"typedef\s+([\w\s\*]+?)\s*\b(fmi" + str(fmi_version) + r"\w+)TYPE\s*\((.*?)\)\s*;"
    for ret, name, params in re.findall(pattern, text, flags=re.S):
        params = " ".join(params.split())
        names, decls = [], []
        if params and params != "void":
            for i, p in enumerate(params.split(",")):
                p = p.strip()
                array = p.endswith("]")
                base = re.sub(r"\[\s*\]\s*$", "", p).strip()
                idents = [w for w in re.findall(r"\w+", base) if w not in ("const", "unsigned", "struct")]
                if len(idents) >= 2:  # drop the header's parameter name
                    base = re.sub(r"\w+\s*$", "", base).strip()
                decls.append(f"{base} a{i}{'[]' if array else ''}")
                names.append(f"a{i}")
        out.append((" ".join(ret.split()), name, ", ".join(decls) if decls else params, names))
    return out


_TYPED_VALUES = re.compile(r"^fmi[23](Get|Set)(Integer|Boolean|Float32|Int8|UInt8|Int16|UInt16|Int32|UInt32|Int64|"
                           r"UInt64|Binary|Clock)$")


def _defined_functions(c_source: str) -> set[str]:
    return set(re.findall(r"^[\w \*]+?\b(fmi[23]\w+)\s*\(", c_source, flags=re.M))


def _stub(fmi_version: int, ret: str, name: str, params: str, names: list[str]) -> str:
    if ret != f"fmi{fmi_version}Status" or not names:
        raise RuntimeError(f"unexpected FMI function type {ret} {name}({params})")
    m = _TYPED_VALUES.match(name)
    body = [f"{ret} {name}({params}) {{", f"    Inst *s = (Inst *){names[0]};"]
    body += [f"    (void){n};" for n in names[1:]]
    body += ["    if (!s) return (" + ret + ")ST_ERROR;", "    s->worst = ST_OK;"]
    if m:
        kind = m.group(2)
        body += [f"    if ({names[2]} == 0) return ({ret})ST_OK;",
                 f'    LOG_ERROR(s, "{name}: this FMU has no {kind} variables (valueReference %u)", '
                 f"(unsigned int){names[1]}[0]);"]
    else:
        body.append(f'    LOG_ERROR(s, "{name}: not supported by this FMU (co-simulation without event mode, '
                    'clocks or derivatives)");')
    body += [f"    return ({ret})ST_ERROR;", "}", ""]
    return "\n".join(body)


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def bridge_source(fmi_version: int, entry_module: str, token: str, log_categories, headers: Path | None = None) -> str:
    """The C source of the bridge of one FMU (FMI ``fmi_version``, 2 or 3): the bridge file for the version with
    the FMU's constants defined, and a stub for every FMI function it does not define."""
    if fmi_version not in (2, 3):
        raise ValueError(f"fmi_version = {fmi_version!r} is not allowed: 2 or 3")
    if not re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", entry_module):
        raise ValueError(f"entry_module = {entry_module!r} is not allowed: a Python identifier")
    body = (BRIDGE_DIR / f"fmi{fmi_version}_bridge.c").read_text()
    defined = _defined_functions(body)
    stubs = [_stub(fmi_version, *f) for f in function_types(fmi_version, headers) if f[1] not in defined]
    cats = ", ".join(_c_string(c) for c in log_categories)
    head = (f"/* generated by gyrosim.fmu.bridge */\n#define ENTRY_MODULE {_c_string(entry_module)}\n"
            f"#define INSTANTIATION_TOKEN {_c_string(token)}\n#define LOG_CATEGORIES {cats}\n")
    return head + body + "\n/* ---- generated: functions this FMU does not support */\n\n" + "\n".join(stubs)


def compile_bridge(fmi_version: int, output: Path, entry_module: str, token: str, log_categories,
                   work_dir: Path) -> Path:
    """Generate and compile the bridge into ``output`` (a shared library).

    Raises
    ------
    RuntimeError
        No C compiler, or the compilation failed (the message carries the compiler's output).
    """
    cc = have_compiler()
    if cc is None:
        raise RuntimeError("no C compiler found (set CC, or install gcc)")
    headers = fmi_headers_dir()
    src = Path(work_dir) / f"fmi{fmi_version}_bridge_gen.c"
    src.write_text(bridge_source(fmi_version, entry_module, token, log_categories, headers))
    cmd = [cc, "-shared", "-fPIC", "-O2", "-std=gnu11", "-Wall", "-Wextra", "-fvisibility=hidden",
           "-I", str(headers), "-I", str(BRIDGE_DIR), "-o", str(output), str(src), "-ldl", "-lpthread", "-lm"]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"compiling the FMI {fmi_version} bridge failed ({' '.join(cmd)}):\n{r.stderr}")
    return Path(output)
