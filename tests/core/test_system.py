"""The engine's one entry-point set (core/engine/gyrosim_system.h): every gs_sys_* gives the bits of the kernel it
dispatches to, as the Python extension calls that kernel today.

The system's functions are not in the extension yet: the engine's sources and system.c are compiled into a shared
library here (with the engine's flags) and called through ctypes, against gyrosim.core._engine's calls of the
one-body and the tree kernel on the same rows.
"""

from __future__ import annotations

import ctypes
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gyrosim.core import _engine
from gyrosim.kernel_tree import tree_layout
from gyrosim.scene import load_scene

ENGINE = Path(__file__).resolve().parents[2] / "src" / "gyrosim" / "core" / "engine"
#: gyrosim_system.h's constants (GS_KERNEL_*, GS_SP_*, GS_SB_*)
SYSTEM = {m[1]: int(m[2]) for m in re.finditer(r"#define GS_((?:KERNEL|SP|SB)_\w+) (\d+)",
                                                (ENGINE / "gyrosim_system.h").read_text())}
CC = shutil.which("cc") or shutil.which("gcc")

pytestmark = pytest.mark.skipif(CC is None, reason="no C compiler (cc or gcc) on PATH")

D = ctypes.POINTER(ctypes.c_double)


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    so = tmp_path_factory.mktemp("system") / "libgssystem.so"
    flags = (ENGINE / "cflags.txt").read_text().split()
    units = sorted(f.name for f in ENGINE.glob("*.c"))   # every .c of the engine folder is a unit
    subprocess.run([CC, *flags, "-fPIC", "-shared", f"-I{ENGINE}", *(str(ENGINE / u) for u in units), "-lm", "-o",
                    str(so)], check=True, capture_output=True, text=True)
    return ctypes.CDLL(str(so))


def _d(a: np.ndarray):
    return a.ctypes.data_as(D)


class System:
    """A gs_system from a description, and its sizes (the struct's first int fields)."""

    def __init__(self, lib, desc):
        self.lib = lib
        self.buf = ctypes.create_string_buffer(1 << 18)   # gs_system: its tree tables are fixed arrays (GS_TREE_MAX)
        d = np.asarray(desc, dtype=np.int32)
        assert lib.gs_sys_init(self.buf, d.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), ctypes.c_size_t(len(d))) == 0
        head = np.frombuffer(self.buf.raw[:4 * 14], dtype=np.int32)
        (self.kernel, self.flags, self.units, self.ny, self.np, self.nout, self.ncoord, self.nwork, self.ndy,
         self.nex, self.nquat, self.drift_slot) = (int(x) for x in head[:12])

    def advance(self, method, y, p, t, H, tol, max_step, hint, stats, ex, status, n=1):
        f = self.lib.gs_sys_advance
        f.restype = ctypes.c_size_t
        return f(self.buf, ctypes.c_size_t(n), method, _d(y), _d(p), ctypes.c_double(t), ctypes.c_double(H),
                 ctypes.c_double(tol), ctypes.c_double(tol), ctypes.c_double(max_step), _d(hint),
                 stats.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)), _d(ex) if ex is not None else None,
                 status.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), 1)

    def trajectory(self, method, y, p, k0, dt, n_out, tol, max_step, hint, stats, ex, status, out, n=1):
        f = self.lib.gs_sys_trajectory
        f.restype = ctypes.c_size_t
        return f(self.buf, ctypes.c_size_t(n), method, _d(y), _d(p), ctypes.c_double(0.0), ctypes.c_int64(k0),
                 ctypes.c_double(dt), ctypes.c_int64(n_out), ctypes.c_double(tol), ctypes.c_double(tol),
                 ctypes.c_double(max_step), _d(hint), stats.ctypes.data_as(ctypes.POINTER(ctypes.c_int64)),
                 _d(ex) if ex is not None else None, status.ctypes.data_as(ctypes.POINTER(ctypes.c_int32)), 1,
                 _d(out))

    def call(self, name, *arrays):
        return getattr(self.lib, name)(self.buf, *(_d(a) if a is not None else None for a in arrays))


def _body_rows(sc):
    """The system's parameter row of a one-body-kernel scene and the engine's rows it stands for."""
    n, nb = len(sc.bodies), SYSTEM["SB_NP"]
    p = np.zeros(SYSTEM["SP_HEAD"] + nb * n)
    pe = np.zeros((n, _engine.NP))
    p[SYSTEM["SP_DRIFT"]] = sc.max_drift
    g = sc.g if sc.gravity else 0.0
    for b, body in enumerate(sc.bodies):
        o = SYSTEM["SP_HEAD"] + nb * b
        p[o:o + 3] = body.moments
        p[o + SYSTEM["SB_MASS"]], p[o + SYSTEM["SB_CM"]], p[o + SYSTEM["SB_G"]] = body.mass, body.cm_distance, g
        p[o + SYSTEM["SB_DAMPING"]] = body.damping
        p[o + SYSTEM["SB_TAU"]:o + SYSTEM["SB_TAU"] + 3] = (0.01, -0.02, 0.005) if sc.torque else 0.0
        pe[b, :3] = body.moments
        pe[b, 3] = body.mass * g * body.cm_distance
        pe[b, 4] = body.damping
        pe[b, 5:8] = p[o + SYSTEM["SB_TAU"]:o + SYSTEM["SB_TAU"] + 3]
        pe[b, 8] = sc.max_drift
    y = np.zeros((n, _engine.NY))
    for b, body in enumerate(sc.bodies):
        y[b, :4], y[b, 4:7] = body.q0, body.omega0
    return p, pe, y


@pytest.mark.parametrize("scene, method", [(None, "rk4"), (None, "adaptive"), ("heavy_top", "splitting"),
                                           ("heavy_top", "dop853"), ("free_body", "exact"), ("gyroscope", "euler")])
def test_body_kernel_gives_the_one_body_engine_bits(lib, scene, method):
    sc = load_scene(scene)
    n = len(sc.bodies)
    p, pe, y0 = _body_rows(sc)
    s = System(lib, [SYSTEM["KERNEL_BODY"], sc.flags, n])
    assert (s.units, s.ny, s.np, s.nout, s.ncoord, s.nwork) == (n, 15 * n, 1 + 10 * n, 15 * n, 7 * n, n)
    code = _engine.METHODS.index(method)
    ya, yb = y0.copy(), y0.copy().ravel()
    assert s.lib.gs_sys_start(s.buf, _d(yb), _d(p), ctypes.byref(ctypes.c_int())) == 0
    assert _engine.start_state(ya, pe) < 0
    assert np.array_equal(ya.ravel(), yb)
    ha, hb = np.zeros(n), np.zeros(n)
    sa, sb = np.zeros((n, 3), np.int64), np.zeros(n * 3, np.int64)
    ea, eb = np.zeros((n, _engine.EX_SIZE)), np.zeros(n * _engine.EX_SIZE)
    st_a, st_b = np.zeros(n, np.int32), np.zeros(n, np.int32)
    for k in range(50):
        t = k * 0.01
        assert _engine.advance(code, sc.flags, ya, pe, t, 0.01, 1e-9, 1e-9, 1e-3, ha, sa, ea, st_a, 1) == 0
        assert s.advance(code, yb, p, t, 0.01, 1e-9, 1e-3, hb, sb, eb, st_b) == 0
    assert np.array_equal(ya.ravel(), yb) and np.array_equal(ha, hb)
    oa, ob = np.zeros((n, _engine.NOUT)), np.zeros(n * _engine.NOUT)
    _engine.outputs(ya, pe, oa)
    s.lib.gs_sys_outputs(s.buf, ctypes.c_size_t(1), _d(yb), _d(p), _d(ob))
    assert np.array_equal(oa.ravel(), ob)
    # a trajectory of two copies of the system (a sweep's rows): each copy the bits of the loop above
    y2, p2 = np.concatenate([yb, yb]), np.concatenate([p, p])
    h2, s2, e2, st2 = np.zeros(2 * n), np.zeros(6 * n, np.int64), np.tile(eb, 2), np.zeros(2 * n, np.int32)
    out = np.zeros((11, 2, n * _engine.NOUT))
    assert s.trajectory(code, y2, p2, 50, 0.01, 10, 1e-9, 1e-3, h2, s2, e2, st2, out, n=2) == 0
    for k in range(50, 60):   # the trajectory's clock: interval k starts at k * dt
        assert s.advance(code, yb, p, k * 0.01, 0.01, 1e-9, 1e-3, hb, sb, eb, st_b) == 0
    if method not in ("adaptive", "dop853"):   # the adaptive methods' trajectory interpolates its output points
        assert np.array_equal(y2[:len(yb)], yb) and np.array_equal(y2[len(yb):], yb)
    assert np.array_equal(out[0, 0], ob) and np.array_equal(out[-1, 0], out[-1, 1])
    dy = np.zeros(s.ndy)
    s.call("gs_sys_derivatives", yb, p, dy)
    assert np.all(np.isfinite(dy)) and dy[:4].any()


def test_tree_kernel_gives_the_tree_engine_bits(lib):
    sc = load_scene("double_pendulum")
    lay = tree_layout(sc)
    p, y0 = lay.params(float(sc.g), float(sc.max_drift)), lay.state()
    s = System(lib, [SYSTEM["KERNEL_TREE"], *lay.desc])
    assert (s.units, s.ny, s.np, s.nout, s.ncoord, s.nwork) == (1, lay.ny, lay.np, lay.nout, lay.nx, 1)
    ya, yb = y0.copy().reshape(1, -1), y0.copy()
    assert _engine.tree_start(lay.desc, ya, p.reshape(1, -1)) < 0
    assert s.lib.gs_sys_start(s.buf, _d(yb), _d(p), ctypes.byref(ctypes.c_int())) == 0
    code = _engine.METHODS.index("rk4")
    ha, hb = np.zeros(1), np.zeros(1)
    sa, sb = np.zeros((1, 3), np.int64), np.zeros(3, np.int64)
    st_a, st_b = np.zeros(1, np.int32), np.zeros(1, np.int32)
    for _ in range(50):
        assert _engine.tree_advance(lay.desc, code, ya, p.reshape(1, -1), 0.01, 1e-9, 1e-9, 1e-3, ha, sa, st_a, 1) == 0
        assert s.advance(code, yb, p, 0.0, 0.01, 1e-9, 1e-3, hb, sb, None, st_b) == 0
    assert np.array_equal(ya[0], yb)
    oa, ob = np.zeros((1, lay.nout)), np.zeros(lay.nout)
    _engine.tree_outputs(lay.desc, ya, p.reshape(1, -1), oa)
    s.lib.gs_sys_outputs(s.buf, ctypes.c_size_t(1), _d(yb), _d(p), _d(ob))
    assert np.array_equal(oa[0], ob)
    assert s.lib.gs_sys_method_allowed(s.buf, _engine.METHODS.index("exact")) == 0
    assert s.lib.gs_sys_method_allowed(s.buf, _engine.METHODS.index("dop853")) == 1


def test_body_directional_is_the_one_body_tree_complex_step(lib):
    """An input's seed on the body kernel: the one-body tree's complex step (a ball joint at the pivot), as the FMU's
    directional derivatives had it."""
    sc = load_scene(None)
    p, _, y = _body_rows(sc)
    y = y.ravel()
    s = System(lib, [SYSTEM["KERNEL_BODY"], sc.flags, 1])
    vp = np.zeros(s.np)
    vp[SYSTEM["SP_HEAD"] + SYSTEM["SB_TAU"] + 1] = 1.0
    ddy, dout = np.zeros(s.ndy), np.zeros(s.nout)
    assert s.call("gs_sys_directional", y, p, None, vp, ddy, dout) == 1
    body = sc.bodies[0]
    desc = np.array([1, 0, -1, _engine.J_BALL], dtype=np.int32)
    _, ty_n, tp_n, _ = _engine.tree_info(desc)
    tp, ty = np.zeros(tp_n), np.zeros(ty_n)
    tp[_engine.TP_G], tp[_engine.TP_DRIFT], tp[_engine.TP_GDIR + 2] = sc.g, sc.max_drift, -1.0
    bp, mass, dist = _engine.TP_HEAD, body.mass, body.cm_distance
    tp[bp + _engine.TB_ROT] = 1.0
    tp[bp + _engine.TB_AXIS + 2], tp[bp + _engine.TB_MASS], tp[bp + _engine.TB_CM + 2] = 1.0, mass, dist
    tp[bp + _engine.TB_I] = body.moments[0] - mass * dist * dist
    tp[bp + _engine.TB_I + 1] = body.moments[1] - mass * dist * dist
    tp[bp + _engine.TB_I + 2] = body.moments[2]
    tp[bp + _engine.TB_DAMP] = body.damping
    tp[bp + _engine.TB_TAU:bp + _engine.TB_TAU + 3] = p[SYSTEM["SP_HEAD"] + SYSTEM["SB_TAU"]:][:3]
    ty[:7] = y[:7]
    tvp = np.zeros(tp_n)
    tvp[bp + _engine.TB_TAU + 1] = 1.0
    nout = _engine.tree_info(desc)[3]
    e = nout - 5   # the tree row: y[0:7], the body's outputs (q_world, r_world, v_world), energy, energy_error, L
    tdy, tout = np.zeros(8), np.zeros(nout)
    _engine.tree_directional(desc, ty.reshape(1, -1), tp.reshape(1, -1), np.zeros(7), tvp, tdy, tout)
    assert np.array_equal(ddy[:7], tdy[:7]) and ddy[7] == tdy[7]
    assert np.array_equal(dout[:7], tout[:7])
    assert np.array_equal(dout[10:13], tout[e + 2:e + 5]) and dout[13] == tout[e] and dout[14] == tout[e + 1]
