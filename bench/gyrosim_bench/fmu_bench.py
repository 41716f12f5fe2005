"""Cost of a doStep of the gyrosim FMU under FMPy's low-level API, against a minimal C FMU doing the same arithmetic.

:func:`run` builds the FMI 2.0 and FMI 3.0 FMUs of the ``heavy_top`` scene (rk4) and two minimal C FMUs
(FMI 2.0 and 3.0: rk4 of the heavy top with the same right-hand side, compiled with gcc -O2 against the FMI
headers FMPy ships), then times ``doStep`` with 1 and 10 internal substeps (``max_step = h`` or ``h/10``),
interleaved so that both see the same machine load, each the best of its rounds in CPU time of the calling thread.
``Model.step`` alone is timed too.
``PYTHONPATH=bench python -m gyrosim_bench.fmu_bench [OUT_DIR]`` (from the checkout root) prints the table.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
import zipfile
from pathlib import Path

__all__ = ["run", "build_c_fmu", "format_table"]

H = 1e-3  # communication step, s

_C_MODEL = r"""
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "fmi@V@Functions.h"

typedef struct { double t, y[7], p[4]; double nsub; int state; } M;   /* q(4) omega(3); I1 I2 I3 mgl */

static void rhs(const double *y, const double *p, double *d) {
    double qw = y[0], qx = y[1], qy = y[2], qz = y[3], w1 = y[4], w2 = y[5], w3 = y[6];
    double I1 = p[0], I2 = p[1], I3 = p[2], mgl = p[3];
    double gx = 2.0 * (qx * qz - qw * qy), gy = 2.0 * (qy * qz + qw * qx);   /* R^T e_z, x and y */
    d[0] = 0.5 * (-qx * w1 - qy * w2 - qz * w3);
    d[1] = 0.5 * (qw * w1 + qy * w3 - qz * w2);
    d[2] = 0.5 * (qw * w2 + qz * w1 - qx * w3);
    d[3] = 0.5 * (qw * w3 + qx * w2 - qy * w1);
    d[4] = ((I2 - I3) * w2 * w3 + mgl * gy) / I1;
    d[5] = ((I3 - I1) * w3 * w1 - mgl * gx) / I2;
    d[6] = ((I1 - I2) * w1 * w2) / I3;
}

static void rk4(M *m, double h) {
    double k1[7], k2[7], k3[7], k4[7], t[7], n;
    int i;
    rhs(m->y, m->p, k1);
    for (i = 0; i < 7; i++) t[i] = m->y[i] + 0.5 * h * k1[i];
    rhs(t, m->p, k2);
    for (i = 0; i < 7; i++) t[i] = m->y[i] + 0.5 * h * k2[i];
    rhs(t, m->p, k3);
    for (i = 0; i < 7; i++) t[i] = m->y[i] + h * k3[i];
    rhs(t, m->p, k4);
    for (i = 0; i < 7; i++) m->y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    n = sqrt(m->y[0] * m->y[0] + m->y[1] * m->y[1] + m->y[2] * m->y[2] + m->y[3] * m->y[3]);
    for (i = 0; i < 4; i++) m->y[i] /= n;
}

static M *new_model(void) {
    M *m = (M *)calloc(1, sizeof(M));
    double c = cos(0.15), s = sin(0.15);
    m->y[0] = c; m->y[2] = s; m->y[6] = 60.0;
    m->p[0] = 1.75e-3; m->p[1] = 1.75e-3; m->p[2] = 1.0e-3; m->p[3] = 0.5 * 9.81 * 0.05;
    m->nsub = 1;
    return m;
}

static int do_step(M *m, double t, double h) {
    int k, n = (int)m->nsub;
    if (h <= 0 || fabs(t - m->t) > 1e-9 * (fabs(t) > 1 ? fabs(t) : 1)) return 3;
    for (k = 0; k < n; k++) rk4(m, h / n);
    m->t = t + h;
    return 0;
}

static int get(M *m, const unsigned int *vr, size_t n, double *v) {
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] == 1) v[i] = m->nsub;
        else if (vr[i] >= 2 && vr[i] <= 8) v[i] = m->y[vr[i] - 2];
        else return 3;
    }
    return 0;
}

static int set(M *m, const unsigned int *vr, size_t n, const double *v) {
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] == 1) m->nsub = v[i];
        else return 3;
    }
    return 0;
}
"""

_C2 = r"""
const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }
fmi2Component fmi2Instantiate(fmi2String a, fmi2Type b, fmi2String c, fmi2String d,
    const fmi2CallbackFunctions *e, fmi2Boolean f, fmi2Boolean g) { return new_model(); }
void fmi2FreeInstance(fmi2Component c) { free(c); }
fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean a, size_t n, const fmi2String x[]) { return fmi2OK; }
fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean a, fmi2Real b, fmi2Real t0, fmi2Boolean d, fmi2Real e) {
    ((M *)c)->t = t0; return fmi2OK; }
fmi2Status fmi2EnterInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2ExitInitializationMode(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Terminate(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2Reset(fmi2Component c) { return fmi2OK; }
fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, fmi2Real v[]) {
    return (fmi2Status)get((M *)c, vr, n, v); }
fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n, const fmi2Real v[]) {
    return (fmi2Status)set((M *)c, vr, n, v); }
fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean x) {
    return (fmi2Status)do_step((M *)c, t, h); }
"""

_C3 = r"""
const char *fmi3GetVersion(void) { return fmi3Version; }
fmi3Instance fmi3InstantiateCoSimulation(fmi3String a, fmi3String b, fmi3String c, fmi3Boolean d, fmi3Boolean e,
    fmi3Boolean f, fmi3Boolean g, const fmi3ValueReference h[], size_t i, fmi3InstanceEnvironment j,
    fmi3LogMessageCallback k, fmi3IntermediateUpdateCallback l) { return new_model(); }
void fmi3FreeInstance(fmi3Instance c) { free(c); }
fmi3Status fmi3EnterInitializationMode(fmi3Instance c, fmi3Boolean a, fmi3Float64 b, fmi3Float64 t0,
    fmi3Boolean d, fmi3Float64 e) { ((M *)c)->t = t0; return fmi3OK; }
fmi3Status fmi3ExitInitializationMode(fmi3Instance c) { return fmi3OK; }
fmi3Status fmi3Terminate(fmi3Instance c) { return fmi3OK; }
fmi3Status fmi3GetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, fmi3Float64 v[], size_t nv) {
    return (fmi3Status)get((M *)c, vr, n, v); }
fmi3Status fmi3SetFloat64(fmi3Instance c, const fmi3ValueReference vr[], size_t n, const fmi3Float64 v[],
    size_t nv) { return (fmi3Status)set((M *)c, vr, n, v); }
fmi3Status fmi3DoStep(fmi3Instance c, fmi3Float64 t, fmi3Float64 h, fmi3Boolean a, fmi3Boolean *b,
    fmi3Boolean *d, fmi3Boolean *e, fmi3Float64 *f) {
    *b = fmi3False; *d = fmi3False; *e = fmi3False; *f = t + h;
    return (fmi3Status)do_step((M *)c, t, h); }
"""

_IMPLEMENTED = {
    2: {"fmi2GetTypesPlatform", "fmi2GetVersion", "fmi2Instantiate", "fmi2FreeInstance", "fmi2SetDebugLogging",
        "fmi2SetupExperiment", "fmi2EnterInitializationMode", "fmi2ExitInitializationMode", "fmi2Terminate",
        "fmi2Reset", "fmi2GetReal", "fmi2SetReal", "fmi2DoStep"},
    3: {"fmi3GetVersion", "fmi3InstantiateCoSimulation", "fmi3FreeInstance", "fmi3EnterInitializationMode",
        "fmi3ExitInitializationMode", "fmi3Terminate", "fmi3GetFloat64", "fmi3SetFloat64", "fmi3DoStep"},
}


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



def _c_source(v: int) -> str:
    stubs = []
    for ret, name, params, _ in function_types(v):
        if name in _IMPLEMENTED[v]:
            continue
        if ret == f"fmi{v}Instance":
            stubs.append(f"{ret} {name}({params}) {{ return NULL; }}")
        else:  # FMPy looks every function up: the others exist and refuse
            stubs.append(f"{ret} {name}({params}) {{ return fmi{v}Error; }}")
    return _C_MODEL.replace("@V@", str(v)) + (_C2 if v == 2 else _C3) + "\n".join(stubs) + "\n"


def _c_model_description(v: int, ident: str) -> str:
    names = ["nsub"] + ["q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"]
    exact = ' initial="exact"'
    if v == 2:
        svs = "".join(
            f'<ScalarVariable name="{n}" valueReference="{i + 1}" causality="{"parameter" if i == 0 else "output"}"'
            f' variability="{"fixed" if i == 0 else "continuous"}"{exact if i else ""}>'
            f'<Real start="{1 if i == 0 else 0}"/></ScalarVariable>' for i, n in enumerate(names))
        outs = "".join(f'<Unknown index="{i}"/>' for i in range(2, 9))
        return (f'<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="2.0" modelName="{ident}" '
                f'guid="{{bench}}"><CoSimulation modelIdentifier="{ident}"/><ModelVariables>{svs}</ModelVariables>'
                f"<ModelStructure><Outputs>{outs}</Outputs></ModelStructure></fmiModelDescription>")
    vs = "".join(f'<Float64 name="{n}" valueReference="{i + 1}" causality="{"parameter" if i == 0 else "output"}" '
                 f'variability="{"fixed" if i == 0 else "continuous"}" start="{1 if i == 0 else 0}"'
                 f'{exact if i else ""}/>' for i, n in enumerate(names))
    outs = "".join(f'<Output valueReference="{i}"/>' for i in range(2, 9))
    return (f'<?xml version="1.0" encoding="UTF-8"?><fmiModelDescription fmiVersion="3.0" modelName="{ident}" '
            f'instantiationToken="{{bench}}"><CoSimulation modelIdentifier="{ident}"/>'
            f'<ModelVariables><Float64 name="time" valueReference="0" causality="independent" '
            f'variability="continuous"/>{vs}</ModelVariables><ModelStructure>{outs}</ModelStructure>'
            "</fmiModelDescription>")


def build_c_fmu(fmi_version: int, out_dir) -> Path:
    """Compile the minimal C FMU (rk4 of the heavy top) with gcc -O2 and zip it into ``out_dir``."""
    from gyrosim.fmu.build import binary_path

    cc = have_compiler()
    if cc is None:
        raise RuntimeError("the benchmark needs a C compiler (gcc)")
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    ident = f"BenchTopC{fmi_version}"
    with tempfile.TemporaryDirectory() as tmp:
        src = Path(tmp) / f"{ident}.c"
        src.write_text(_c_source(fmi_version))
        so = Path(tmp) / f"{ident}.so"
        subprocess.run([cc, "-shared", "-fPIC", "-O2", "-I", str(fmi_headers_dir()), "-o", str(so), str(src),
                        "-lm"], check=True, capture_output=True, text=True)
        fmu = out_dir / f"{ident}.fmu"
        with zipfile.ZipFile(fmu, "w") as z:
            z.writestr("modelDescription.xml", _c_model_description(fmi_version, ident))
            z.write(so, binary_path(fmi_version, ident))
    return fmu


def _time_dosteps(path, version: int, nsub: int, n: int, gyrosim_fmu: bool) -> float:
    """µs per doStep of the FMU at ``path`` (FMPy low-level API), best of 3 runs of ``n`` steps."""
    from fmpy import extract, read_model_description
    from fmpy.fmi2 import FMU2Slave
    from fmpy.fmi3 import FMU3Slave

    md = read_model_description(str(path))
    d = extract(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    cls = FMU2Slave if version == 2 else FMU3Slave
    fmu = cls(guid=md.guid, unzipDirectory=d, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="b")
    fmu.instantiate()
    if version == 2:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
    else:
        fmu.enterInitializationMode(startTime=0.0)
    if gyrosim_fmu:
        fmu.setString([vr["integrator"]], ["rk4"])
        setter = fmu.setReal if version == 2 else fmu.setFloat64
        setter([vr["max_step"]], [H / nsub])
    else:
        (fmu.setReal if version == 2 else fmu.setFloat64)([vr["nsub"]], [float(nsub)])
    fmu.exitInitializationMode()
    step = fmu.doStep
    t = 0.0
    for k in range(200):  # warm-up (caches)
        step(t, H)
        t = (k + 1) * H
    best = float("inf")
    i = 200
    for _ in range(3):
        t0 = time.thread_time()  # CPU time of this thread: preemption by other jobs does not count
        for _ in range(n):
            step(i * H, H)
            i += 1
        best = min(best, (time.thread_time() - t0) / n * 1e6)
    fmu.terminate()
    fmu.freeInstance()
    return best


def _time_model(nsub: int, n: int) -> float:
    from gyrosim.model import Model

    m = Model("heavy_top", parameters={"integrator": "rk4", "max_step": H / nsub})
    for _ in range(200):
        m.step(H)
    best = float("inf")
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(n):
            m.step(H)
        best = min(best, (time.perf_counter() - t0) / n * 1e6)
    return best


def run(out_dir, n: int = 20000) -> list[dict]:
    """Time doStep of the gyrosim FMUs and the minimal C FMUs (1 and 10 substeps); write ``bench_fmu.json``/``.md``.

    Returns
    -------
    list of dict
        One row per (FMI version, substeps): ``gyrosim_us`` and ``c_us`` per doStep (best of interleaved rounds),
        ``ratio`` (gyrosim_us / c_us) and ``model_step_us`` (Model.step alone, no FMU).
    """
    from gyrosim.fmu.build import build_fmu

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    rows = []
    model_us = {nsub: _time_model(nsub, n) for nsub in (1, 10)}
    for v in (2, 3):
        g = build_fmu("heavy_top", v, out_dir / f"fmi{v}")
        c = build_c_fmu(v, out_dir / f"fmi{v}")
        for nsub in (1, 10):
            g_us, c_us = float("inf"), float("inf")
            for _ in range(7):  # interleaved rounds: both see the same load
                g_us = min(g_us, _time_dosteps(g, v, nsub, n, True))
                c_us = min(c_us, _time_dosteps(c, v, nsub, n, False))
            rows.append({"fmi_version": v, "substeps": nsub, "gyrosim_us": round(g_us, 3), "c_us": round(c_us, 3),
                         "ratio": round(g_us / c_us, 3), "model_step_us": round(model_us[nsub], 3)})
    (out_dir / "bench_fmu.json").write_text(json.dumps(rows, indent=1))
    (out_dir / "bench_fmu.md").write_text(format_table(rows) + "\n")
    return rows


def format_table(rows) -> str:
    """Markdown table of :func:`run`'s rows."""
    lines = ["| FMI | substeps | gyrosim FMU µs/doStep | minimal C FMU µs/doStep | ratio | Model.step µs |",
             "|---|---:|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['fmi_version']}.0 | {r['substeps']} | {r['gyrosim_us']:.3f} | {r['c_us']:.3f} | "
                     f"{r['ratio']:.3f} | {r['model_step_us']:.2f} |")
    return "\n".join(lines)


if __name__ == "__main__":  # pragma: no cover
    print(format_table(run(sys.argv[1] if len(sys.argv) > 1 else "fmu/dist/bench")))
