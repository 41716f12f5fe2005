"""The step-based model of a tree scene (bodies joined by joints, DESIGN.md section 4b) on the engine's tree.

``Model(scene)`` returns a :class:`TreeModel` when the scene is a tree, so ``gyrosim simulate``, the service and the
FMU glue drive it as they drive a one-body model: ``set``/``get`` by variable name (``rotor.angle``, or ``angle``
with ``body="rotor"``), ``step(h)``, ``trajectory(dt, n)``, ``outputs()``, and exact state save and restore. Every
step is one call of the C engine (``gs_tree_advance``), which the FMUs compile too.
"""

from __future__ import annotations

import copy
import math
import pickle

import numpy as np

from .core import _engine
from .core.tree import BODY_OUTPUTS, SCENE_OUTPUTS, TreeLayout
from .errors import ConfigError, IntegrationError, StepError
from .model import Model, ModelState, Variable, _positive_step
from .scene import TREE_INTEGRATORS, Scene, did_you_mean, load_scene
from .scene_tree import BALL_PARAMS, BODY_PARAMS, HINGE_PARAMS, body_with

__all__ = ["TreeModel", "tree_variables", "tree_output_names"]

_METHOD_CODES = {name: code for code, name in enumerate(_engine.METHODS)}
_COORD_META = {
    "q_w": ("1", "attitude quaternion relative to the parent, scalar part"),
    "q_x": ("1", "attitude quaternion relative to the parent, x part"),
    "q_y": ("1", "attitude quaternion relative to the parent, y part"),
    "q_z": ("1", "attitude quaternion relative to the parent, z part"),
    "omega_x": ("rad/s", "angular velocity relative to the parent, body x"),
    "omega_y": ("rad/s", "angular velocity relative to the parent, body y"),
    "omega_z": ("rad/s", "angular velocity relative to the parent, body z"),
    "r_x": ("m", "position of the body's origin, world x"),
    "r_y": ("m", "position of the body's origin, world y"),
    "r_z": ("m", "position of the body's origin, world z"),
    "v_x": ("m/s", "velocity of the body's origin, world x"),
    "v_y": ("m/s", "velocity of the body's origin, world y"),
    "v_z": ("m/s", "velocity of the body's origin, world z"),
    "angle": ("rad", "hinge angle, unwrapped"),
    "rate": ("rad/s", "hinge rate"),
}
_SCENE_OUT_META = {
    "energy": ("J", "kinetic plus potential energy of the whole tree (gravity and springs)"),
    "energy_error": ("J", "work-energy balance E(t) - E(0) - W_inputs(t) + W_damping(t)"),
    "L_x": ("kg.m2/s", "total angular momentum about the world origin, world x"),
    "L_y": ("kg.m2/s", "total angular momentum about the world origin, world y"),
    "L_z": ("kg.m2/s", "total angular momentum about the world origin, world z"),
}


def tree_output_names(scene: Scene) -> list[str]:
    """The output columns of a tree scene's engine rows: ``<body>.<coordinate>``, ``<body>.q_world_*``, then the
    scene-wide ``energy``, ``energy_error``, ``L_x``, ``L_y``, ``L_z``."""
    names = scene.body_names
    out = []
    for b, body in enumerate(scene.tree):
        out += [f"{names[b]}.{c}" for c in body.coords]
    for b in range(len(scene.tree)):
        out += [f"{names[b]}.{c}" for c in BODY_OUTPUTS]
    return out + list(SCENE_OUTPUTS)


def _body_param_value(b, name: str) -> float:
    if name == "mass":
        return float(b.mass)
    if name in ("I1", "I2", "I3"):
        k = int(name[1]) - 1
        return float(np.asarray(b.inertia)[k, k])
    if name.startswith(("cm_", "pos_")):
        head, tail = name.split("_")
        return float(np.asarray(getattr(b, head))["xyz".index(tail)])
    if name in ("joint_damping", "damping"):
        return float(b.damping)
    return float(getattr(b, name))


def tree_variables(scene: Scene) -> dict[str, Variable]:
    """Every variable of a tree scene by its full name (``<body>.<name>``; scene-wide names bare)."""
    from .scene import INTEGRATORS

    V = [Variable("g", "parameter", "fixed", "Real", "m/s2", "gravitational acceleration along -z", float(scene.g))]
    for a in scene.aliases:
        V.append(Variable(a.name, "parameter", "fixed", "Real", a.unit, a.description, float(a.value)))
    for name, (_, _, k) in zip(scene.coupling_names, scene.couplings):
        V.append(Variable(name, "parameter", "fixed", "Real", "N.m/rad", "torsion spring between two hinges",
                          float(k)))
    V += [Variable("integrator", "parameter", "fixed", "String", "",
                   "integrator: " + ", ".join(TREE_INTEGRATORS) + " (a tree; " +
                   ", ".join(i for i in INTEGRATORS if i not in TREE_INTEGRATORS) + " solve one body)",
                   scene.integrator),
          Variable("max_step", "parameter", "fixed", "Real", "s",
                   "largest internal step; euler and rk4 take h/max_step substeps rounded up", float(scene.max_step)),
          Variable("max_drift", "parameter", "fixed", "Real", "1",
                   "relative drift of the energy balance and the angular momentum beyond which a step counts as "
                   "blown up (0: off)", float(scene.max_drift))]
    for b in scene.tree:
        pre = f"{b.name}."
        params = dict(BODY_PARAMS)
        if b.joint == "hinge":
            params.update(HINGE_PARAMS)
        elif b.joint in ("ball", "free_rotation", "free"):
            params.update(BALL_PARAMS)
        for n, (unit, desc) in params.items():
            V.append(Variable(pre + n, "parameter", "fixed", "Real", unit, desc, _body_param_value(b, n)))
        if b.motor_input:
            V.append(Variable(pre + "motor_torque", "input", "continuous", "Real", "N.m",
                              "motor torque about the hinge axis (on this body; its reaction on the parent)", 0.0))
        if b.torque_input:
            for n in ("tau_x", "tau_y", "tau_z"):
                V.append(Variable(pre + n, "input", "continuous", "Real", "N.m",
                                  f"external torque about body {n[-1]}, held over each step", 0.0))
        start = {"q": list(b.q0), "omega": list(b.omega0), "r": list(b.r0), "v": list(b.v0)}
        for c in b.coords:
            unit, desc = _COORD_META[c]
            if c in ("angle", "rate"):
                s = float(b.angle0 if c == "angle" else b.rate0)
            else:
                head, tail = c.rsplit("_", 1)
                s = float(start[head]["wxyz".index(tail) if head == "q" else "xyz".index(tail)])
            V.append(Variable(pre + c, "output", "continuous", "Real", unit, desc, s))
        for c in BODY_OUTPUTS:
            V.append(Variable(pre + c, "output", "continuous", "Real", "1",
                              f"attitude in the world, {c[-1]} part (body to world)", None))
    for n, (unit, desc) in _SCENE_OUT_META.items():
        V.append(Variable(n, "output", "continuous", "Real", unit, desc, None))
    return {v.name: v for v in V}


class TreeModel(Model):
    """Step-based model of a tree of bodies (built by ``Model(scene)`` for a tree scene).

    Variables are named ``<body>.<name>`` (``rotor.angle``, ``wheel_x.motor_torque``); the scene-wide ones bare
    (``energy``, ``L_z``, ``g``, ``integrator``). ``set``, ``get`` and ``outputs`` take the full name, or the body's
    own name with ``body=``.

    Examples
    --------
    >>> m = Model("double_pendulum", parameters={"integrator": "rk4"})
    >>> m.step(0.01)
    >>> round(m.get("upper.angle"), 6) < 1.0
    True
    """

    def __init__(self, scene=None, *, parameters: dict | None = None, start_time: float = 0.0,
                 stop_time: float | None = None, tolerance: float | None = None):
        self.scene = sc = load_scene(scene)
        if not sc.is_tree:
            raise ConfigError("scene", sc.name, "a tree scene (bodies with parent/joint)")
        self.layout = TreeLayout(sc.tree, sc.couplings)
        self.variables = tree_variables(sc)
        self.body_names = sc.body_names
        self.n_bodies = len(self.body_names)
        self._index = {b: i for i, b in enumerate(self.body_names)}
        self._out_names = tree_output_names(sc)
        self._out_index = {n: i for i, n in enumerate(self._out_names)}
        self._bodies = list(sc.tree)
        self._couplings = [k for _, _, k in sc.couplings]
        self._aliases = {a.name: float(a.value) for a in sc.aliases}
        self._g = float(sc.g)
        self._motor = np.zeros(self.n_bodies)
        self._tau = np.zeros((self.n_bodies, 3))
        self._y = self.layout.state().reshape(1, -1)
        self._hint = np.zeros(1)
        self._stats = np.zeros((1, 3), dtype=np.int64)
        self._status = np.zeros(1, dtype=np.int32)
        self.integrator = sc.integrator
        self.max_step = float(sc.max_step)
        self.max_drift = float(sc.max_drift)
        self.tolerance = float(sc.tolerance if tolerance is None else tolerance)
        if tolerance is not None:
            self._check_positive("tolerance", self.tolerance)
        self.start_time = float(start_time)
        self.stop_time = None if stop_time is None else float(stop_time)
        self._t_base = self.start_time
        self._n = 0
        self._h = 0.0
        self._initialized = False
        self._state_dirty = True
        self._out = None
        self._p = None
        for k, v in (parameters or {}).items():
            self.set(k, v)

    # ----------------------------------------------------------------------------------------------- variables
    def _full(self, name, body) -> str:
        if body is None or (isinstance(name, str) and "." in name):
            return str(name)
        if isinstance(body, (int, np.integer)):
            if not -self.n_bodies <= body < self.n_bodies:
                raise ConfigError("body", body, f"a body index in [0, {self.n_bodies}) or a body name")
            body = self.body_names[int(body)]
        if body not in self._index:
            raise ConfigError("body", body, f"one of {', '.join(self.body_names)}")
        return f"{body}.{name}"

    def _var(self, name) -> Variable:
        v = self.variables.get(name)
        if v is None:
            raise ConfigError("variable", name, f"a variable of scene {self.scene.name!r}"
                              f"{did_you_mean(name, self.variables)}: " + ", ".join(list(self.variables)[:40]))
        return v

    def set(self, name: str, value, body=None) -> None:
        """Set a parameter, input or start state by name (``rotor.rate``; or ``rate`` with ``body="rotor"``).

        Raises
        ------
        ConfigError
            Unknown name, a derived output, or a value that is not allowed (named with the rule).
        """
        name = self._full(name, body)
        v = self._var(name)
        if v.type == "String":
            if value not in TREE_INTEGRATORS:
                from .scene import INTEGRATORS

                why = (f"{value!r} solves one body; a tree of bodies takes one of "
                       if value in INTEGRATORS else "one of ")
                raise ConfigError("integrator", value, why + ", ".join(TREE_INTEGRATORS)
                                  + did_you_mean(value, TREE_INTEGRATORS))
            if value != self.integrator:
                self._hint[:] = 0.0
            self.integrator = value
            return
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ConfigError(name, value, f"a real number in {v.unit or '1'}") from None
        if not math.isfinite(x):
            raise ConfigError(name, value, f"a finite number in {v.unit or '1'}")
        bname, _, short = name.rpartition(".")
        if name == "max_step":
            self._check_positive(name, x)
            self.max_step = x
        elif name == "max_drift":
            if x < 0:
                raise ConfigError(name, value, "a number >= 0 (0: the health monitor off)")
            self.max_drift = x
            if self._p is not None:
                self._p[:, 1] = x
        elif name == "g":
            if x < 0:
                raise ConfigError(name, value, "a number >= 0 in m/s2")
            self._g = x
            self._initialized = False
        elif name in self._aliases:
            a = next(a for a in self.scene.aliases if a.name == name)
            for bi, pn, f in a.sets:
                self._check_body_param(pn, f * x, self.body_names[bi], name)
            self._aliases[name] = x
            for bi, pn, f in a.sets:
                self._bodies[bi] = body_with(self._bodies[bi], pn, f * x)
            self._initialized = False
        elif name in self.scene.coupling_names:
            if x < 0:
                raise ConfigError(name, value, "a number >= 0 in N.m/rad")
            self._couplings[self.scene.coupling_names.index(name)] = x
            self._initialized = False
        elif v.causality == "input":
            i = self._index[bname]
            if short == "motor_torque":
                self._motor[i] = x
                if self._p is not None:
                    self._p[0, self.layout.body_offset(i) + _engine.TB_MOTOR] = x
            else:
                k = "xyz".index(short[-1])
                self._tau[i, k] = x
                if self._p is not None:
                    self._p[0, self.layout.body_offset(i) + _engine.TB_TAU + k] = x
        elif v.causality == "parameter":
            i = self._index[bname]
            self._check_body_param(short, x, bname, name)
            self._bodies[i] = body_with(self._bodies[i], short, x)
            self._initialized = False
        elif v.start is not None:  # a joint coordinate: a start state
            self._y[0, self.layout.coord_slots[(self._index[bname], short)]] = x
            self._state_dirty = True
            self._out = None
        else:
            raise ConfigError(name, value, "a parameter, an input or a joint's start state; "
                              f"{name} is a derived output")

    @staticmethod
    def _check_body_param(short, x, bname, name):
        if short in ("mass", "I1", "I2", "I3", "stiffness", "joint_damping", "damping") and x < 0:
            raise ConfigError(name, x, f"a number >= 0 ({short} of body {bname!r})")

    def set_many(self, name: str, values) -> None:
        raise ConfigError(name, "an array", "one value: a tree scene is one system (use Model.set)")

    def get(self, name: str, body=None):
        """Value of a variable by full name (or the body's own name with ``body=``)."""
        name = self._full(name, body)
        v = self._var(name)
        if v.type == "String":
            return self.integrator
        if v.causality == "output":
            return float(self._outputs_array()[0, self._out_index[name]])
        bname, _, short = name.rpartition(".")
        if name == "max_step":
            return self.max_step
        if name == "max_drift":
            return self.max_drift
        if name == "g":
            return self._g
        if name in self._aliases:
            return self._aliases[name]
        if name in self.scene.coupling_names:
            return self._couplings[self.scene.coupling_names.index(name)]
        i = self._index[bname]
        if short == "motor_torque":
            return float(self._motor[i])
        if short in ("tau_x", "tau_y", "tau_z"):
            return float(self._tau[i, "xyz".index(short[-1])])
        return _body_param_value(self._bodies[i], short)

    def outputs(self, body=None) -> dict[str, float]:
        """Every output by full name (``body``: only that body's, by its own names)."""
        row = self._outputs_array()[0]
        if body is None:
            return {n: float(row[k]) for k, n in enumerate(self._out_names)}
        pre = self._full("", body)
        return {n[len(pre):]: float(row[k]) for k, n in enumerate(self._out_names) if n.startswith(pre)}

    def outputs_array(self) -> np.ndarray:
        """(1, nout) outputs in the order of :func:`tree_output_names` (a copy)."""
        return self._outputs_array().copy()

    def parameters(self, body=None) -> dict:
        return {n: self.get(n) for n, v in self.variables.items() if v.causality == "parameter"}

    def inputs(self, body=None) -> dict[str, float]:
        return {n: self.get(n) for n, v in self.variables.items() if v.causality == "input"}

    # ----------------------------------------------------------------------------------------------- stepping
    def _params(self) -> np.ndarray:
        lay = TreeLayout(self._bodies, [(a, b, k) for (a, b, _), k in zip(self.scene.couplings, self._couplings)])
        p = lay.params(self._g, self.max_drift)
        for i in range(self.n_bodies):
            o = self.layout.body_offset(i)
            p[o + _engine.TB_MOTOR] = self._motor[i]
            p[o + _engine.TB_TAU:o + _engine.TB_TAU + 3] = self._tau[i]
        return p.reshape(1, -1)

    def initialize(self) -> None:
        """Build the parameter row and start the state (quaternions normalised, the health monitor started)."""
        p_old = self._p if not self._state_dirty else None
        if not self._initialized:
            self._p = self._params()
            self._initialized = True
            if p_old is not None:
                _engine.tree_reparam(self.layout.desc, self._y, p_old, self._p)
        if self._state_dirty:
            bad = _engine.tree_start(self.layout.desc, self._y, self._p)
            if bad >= 0:
                for b, body in enumerate(self._bodies):
                    if body.joint in ("ball", "free_rotation", "free"):
                        k = self.layout.coord_slots[(b, "q_w")]
                        q = self._y[0, k:k + 4]
                        if not np.linalg.norm(q) > 0:
                            raise ConfigError(f"{body.name}.q", q.tolist(), "a non-zero quaternion (it is normalised)")
                raise ConfigError("state", self._y[0, :self.layout.nx].tolist(), "finite start values")
            self._state_dirty = False
            self._out = None

    def _check_call(self, h: float, what: str) -> None:
        if self.integrator in ("euler", "rk4") and _engine.substeps(h, self.max_step) == 0:
            raise StepError(f"a {what} of {h!r} s with max_step = {self.max_step!r} s needs {h / self.max_step:.3g} "
                            f"internal steps, more than the {_engine.MAX_WORK:,} one call may take; raise max_step "
                            "or take shorter steps")

    def _step_engine(self, h: float, t: float) -> None:
        method = _METHOD_CODES[self.integrator]
        saved = (self._y.copy(), self._hint.copy())
        failed = _engine.tree_advance(self.layout.desc, method, self._y, self._p, h, self.tolerance, self.tolerance,
                                      self.max_step, self._hint, self._stats, self._status, 0)
        if failed:
            k = int(self._status[0])
            self._status[:] = 0
            self._y, self._hint = saved
            raise IntegrationError(self._blowup(self._y[0], t, h, k, f"the step from t = {t!r} s with h = {h!r} s"))

    def step(self, h: float) -> None:
        """Advance one communication step of ``h`` s, holding the inputs (see :meth:`Model.step`)."""
        h = _positive_step(h, "communication step h")
        t = self.time
        if self.stop_time is not None and t + h > self.stop_time + 1e-9 * max(1.0, abs(self.stop_time)):
            raise StepError(f"a step of h = {h!r} s from t = {t!r} s ends at {t + h!r} s, after the stop time "
                            f"{self.stop_time!r} s")
        if not self._initialized or self._state_dirty:
            self.initialize()
        self._check_call(h, "communication step h")
        self._step_engine(h, t)
        if h == self._h:
            self._n += 1
        else:
            self._t_base = t
            self._n = 1
            self._h = h
        self._out = None

    def gimbal_lock(self, y=None) -> str | None:
        """A message naming gimbal lock when two hinge axes of a chain line up at the state ``y`` (default: now)
        and the bodies between them carry (almost) no inertia about the lost axis, else None."""
        y = self._y[0] if y is None else y
        hinges = [i for i, b in enumerate(self._bodies) if b.joint == "hinge"]
        from .core.rotations import quat_to_matrix

        out = np.empty(self.layout.nout)
        _engine.tree_outputs(self.layout.desc, y.reshape(1, -1), self._p, out)
        qw = {i: out[self.layout.nx + 4 * i:self.layout.nx + 4 * i + 4] for i in range(self.n_bodies)}

        def axis_world(i):
            b = self._bodies[i]
            R = np.eye(3) if b.parent < 0 else quat_to_matrix(qw[b.parent])
            return R @ np.asarray(b.axis)

        for i in hinges:
            j = self._bodies[i].parent
            while j >= 0 and self._bodies[j].joint == "hinge":
                if abs(float(np.dot(axis_world(i), axis_world(j)))) > math.cos(0.1):
                    ang = math.acos(min(1.0, abs(float(np.dot(axis_world(i), axis_world(j))))))
                    return (f"gimbal lock: the axes of {self._bodies[j].name!r} and {self._bodies[i].name!r} are "
                            f"{ang:.3g} rad from lining up, where the gimbals between them carry too little inertia "
                            "about the lost axis (massless gimbals make the motion singular there); give the gimbals "
                            "inertia, or keep the inner angle away from 0")
                j = self._bodies[j].parent
        return None

    def _blowup(self, y0: np.ndarray, t: float, h: float, k: int, where: str) -> str:
        lock = self.gimbal_lock(y0)
        rate = float(_engine.tree_scalar(self.layout.desc, y0.reshape(1, -1), self._p, 1))
        n_sub = _engine.substeps(h, self.max_step) if self.integrator in ("euler", "rk4") else 0
        at = f" at internal step {k} of {n_sub}" if n_sub > 1 else ""
        y = y0.reshape(1, -1).copy()
        p = self._p.copy()
        p[:, 1] = 0.0
        hint, stats, st = self._hint.copy(), np.zeros((1, 3), dtype=np.int64), np.zeros(1, dtype=np.int32)
        fails = _engine.tree_advance(self.layout.desc, _METHOD_CODES[self.integrator], y, p, h, self.tolerance,
                                     self.tolerance, self.max_step, hint, stats, st, 1)
        if fails:
            cause = f"the state became non-finite or overflowed{at}"
        else:
            d = np.empty((1, 2))
            _engine.tree_drift(self.layout.desc, y, self._p, d)
            i = int(np.argmax(d[0]))
            cause = (f"{('the energy balance', 'the angular momentum')[i]} drifted by {d[0, i]:.3g} of its scale{at} "
                     f"(max_drift = {self.max_drift:g}, the health monitor's bound)")
        if lock:
            advice = lock
        elif self.integrator in ("adaptive", "dop853"):
            advice = "tighten or loosen the tolerance, check the parameters, or try the integrator 'rk4'"
        elif rate > 0:
            advice = (f"the fastest rate in the state is {rate:.4g} rad/s; use max_step <= {0.5 / rate:.3g} s or the "
                      "integrator 'dop853'")
        else:
            advice = "check the parameters, or try the integrator 'dop853'"
        return f"integrator {self.integrator!r} blew up in {where}: {cause}; {advice}"

    def trajectory(self, dt: float, n: int, *, angles: bool = True, momentum: bool = True,
                   status: np.ndarray | None = None) -> np.ndarray:
        """Advance ``n`` output intervals of ``dt`` s in one engine call: the bits of ``n`` calls of :meth:`step`.

        Returns
        -------
        (n + 1, 1, nout) ndarray
            The outputs (:func:`tree_output_names`) at ``time + k*dt``, ``k = 0..n``.
        """
        del angles, momentum  # every output of a tree is computed
        keep_going = status is not None
        dt = _positive_step(dt, "output interval dt")
        if not (isinstance(n, (int, np.integer)) and n >= 0):
            raise StepError(f"n = {n!r} is not allowed: a number of output intervals >= 0")
        n = int(n)
        t = self.time
        if self.stop_time is not None and t + n * dt > self.stop_time + 1e-9 * max(1.0, abs(self.stop_time)):
            raise StepError(f"a run of {n} intervals of {dt!r} s from t = {t!r} s ends at {t + n * dt!r} s, after "
                            f"the stop time {self.stop_time!r} s")
        if not self._initialized or self._state_dirty:
            self.initialize()
        self._check_call(dt, "output interval dt")
        out = np.empty((n + 1, 1, self.layout.nout))
        st = status if keep_going else np.zeros(1, dtype=np.int32)
        saved = (self._y.copy(), self._hint.copy())
        failed = _engine.tree_trajectory(self.layout.desc, _METHOD_CODES[self.integrator], self._y, self._p, dt, n,
                                         self.tolerance, self.tolerance, self.max_step, self._hint, self._stats, st,
                                         0, out)
        if failed and not keep_going:
            k = int(st[0])
            t_k = t + (k - 1) * dt
            msg = self._blowup(self._y[0], t_k, dt, 1, f"the output interval from t = {t_k!r} s to {t + k * dt!r} s "
                               f"(interval {k} of {n})")
            self._y, self._hint = saved
            err = IntegrationError(msg)
            err.rows = out[:k]
            raise err
        done = n if not failed else int(st[0]) - 1
        if done:
            if dt == self._h:
                self._n += done
            else:
                self._t_base = t
                self._n = done
                self._h = dt
        self._out = None
        return out

    def _outputs_array(self) -> np.ndarray:
        if self._out is None:
            if not self._initialized or self._state_dirty:
                self.initialize()
            out = np.empty((1, self.layout.nout))
            _engine.tree_outputs(self.layout.desc, self._y, self._p, out)
            self._out = out
        return self._out

    # ----------------------------------------------------------------------------------------------- state
    _STATE_FIELDS = ("_bodies", "_couplings", "_aliases", "_g", "_motor", "_tau", "_y", "_hint", "_stats", "_p",
                     "integrator", "max_step", "max_drift", "tolerance", "start_time", "stop_time", "_t_base", "_n",
                     "_h", "_initialized", "_state_dirty")

    def get_state(self) -> ModelState:
        """Snapshot of the whole state, exact to the bit."""
        return ModelState({k: copy.deepcopy(getattr(self, k)) for k in self._STATE_FIELDS})

    def set_state(self, state: ModelState) -> None:
        """Restore a snapshot taken with :meth:`get_state` of a model of the same scene."""
        if not isinstance(state, ModelState) or set(state.data) != set(self._STATE_FIELDS):
            raise ConfigError("state", type(state).__name__, "a ModelState from TreeModel.get_state()")
        if state.data["_y"].shape != self._y.shape:
            raise ConfigError("state", f"a state of {state.data['_y'].shape[1]} values",
                              f"a state of this scene ({self._y.shape[1]} values)")
        for k, v in state.data.items():
            setattr(self, k, copy.deepcopy(v))
        self._out = None

    def state_bytes(self) -> bytes:
        return pickle.dumps(self.get_state().data, protocol=pickle.HIGHEST_PROTOCOL)
