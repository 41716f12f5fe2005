"""The model's operations on the one-body kernel: independent bodies, each integrated by Euler's equations in closed
form, with the exact flows (torque-free body, Lagrange top) and the splittings (docs/trees.md: the engine picks
this kernel for a lone free_rotation or ball root without springs or orbit).

:class:`BodyKernel` maps the variable names of fmu/README.md section 4 onto the C engine's one-body rows
(:mod:`gyrosim.core._engine`, ``core/engine/gyrosim_engine.h``). Its functions are the :class:`gyrosim.model.Model`'s
own (``self`` is the model): the model calls the kernel its scene was set up with.
"""

from __future__ import annotations

import math

import numpy as np

from .core import _engine
from .core.inertia import TRIANGLE_RTOL, check_principal_moments
from .core.rotations import quat_to_euler_zyz
from .errors import ConfigError, IntegrationError
from .ranges import BOUNDED, BOUNDED_NONNEGATIVE, NONNEGATIVE, POSITIVE
from .scene import INTEGRATORS, Scene, did_you_mean
from .variables import Variable

__all__ = ["BodyKernel", "variables_for", "OUTPUT_NAMES", "STATE_NAMES"]

_METHOD_CODES = {name: code for code, name in enumerate(_engine.METHODS)}

OUTPUT_NAMES = ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z", "phi", "theta", "psi",
                "L_x", "L_y", "L_z", "energy", "energy_error")
#: A body's continuous coordinates, the head of its state row and of its outputs.
STATE_NAMES = OUTPUT_NAMES[:7]
_FIXED = ("euler", "rk4", "splitting", "splitting4", "strang_exact", "yoshida_exact", "bm4_exact", "bm6_exact")
#: The variables that enter the engine's parameter rows.
_PARAM_NAMES = frozenset(("I1", "I2", "I3", "mass", "cm_distance", "g", "damping", "tau_x", "tau_y", "tau_z",
                          "max_drift"))


def _want(angles: bool, momentum: bool) -> int:
    """The engine's selection of derived outputs (OUT_ANGLES, OUT_MOMENTUM) of a trajectory."""
    return (_engine.OUT_ANGLES if angles else 0) | (_engine.OUT_MOMENTUM if momentum else 0)


def variables_for(scene: Scene, body: int = 0) -> dict[str, Variable]:
    """The variables (name -> :class:`Variable`) that ``scene`` carries, with the start values of ``body``."""
    b = scene.bodies[body]
    V = []
    for i, n in enumerate(("I1", "I2", "I3")):
        V.append(Variable(n, "parameter", "fixed", "Real", "kg.m2",
                          f"principal moment of inertia {i + 1}" + (" about the pivot" if scene.gravity else ""),
                          float(b.moments[i]), **POSITIVE.fields()))
    if scene.gravity:
        V += [Variable("mass", "parameter", "fixed", "Real", "kg", "mass of the body", float(b.mass),
                       **POSITIVE.fields()),
              Variable("cm_distance", "parameter", "fixed", "Real", "m",
                       "distance from the pivot to the centre of mass along body +z", float(b.cm_distance),
                       **NONNEGATIVE.fields()),
              Variable("g", "parameter", "fixed", "Real", "m/s2", "gravitational acceleration along -z",
                       float(scene.g), **BOUNDED_NONNEGATIVE.fields())]
    if scene.damping:
        V.append(Variable("damping", "parameter", "fixed", "Real", "N.m.s", "viscous torque -damping*omega",
                          float(b.damping), **NONNEGATIVE.fields()))
    V += [Variable("integrator", "parameter", "fixed", "String", "",
                   "integrator: " + ", ".join(INTEGRATORS) + (
                       "" if scene.torque_free else " (exact: while the body is torque-free or a Lagrange top)"),
                   scene.integrator),
          Variable("max_step", "parameter", "fixed", "Real", "s",
                   "largest internal step; fixed-step integrators take h/max_step substeps rounded up (a ratio within "
                   f"1e-9 of a whole number takes it), at most {_engine.MAX_WORK:,} per step",
                   float(scene.max_step), **POSITIVE.fields()),
          Variable("max_drift", "parameter", "fixed", "Real", "1",
                   "relative drift of the energy balance and the invariants beyond which a step counts as blown up "
                   "(0: off)", float(scene.max_drift), **NONNEGATIVE.fields())]
    for n, v, d in zip(("q_w", "q_x", "q_y", "q_z"), b.q0, ("scalar", "x", "y", "z")):
        V.append(Variable(n, "output", "continuous", "Real", "1",
                          f"attitude quaternion, {d} part (body to world)", float(v)))
    for n, v in zip(("omega_x", "omega_y", "omega_z"), b.omega0):
        V.append(Variable(n, "output", "continuous", "Real", "rad/s",
                          f"body-frame angular velocity about body {n[-1]}", float(v), **BOUNDED.fields()))
    if scene.torque:
        for n in ("tau_x", "tau_y", "tau_z"):
            V.append(Variable(n, "input", "continuous", "Real", "N.m",
                              f"external torque about body {n[-1]}, held over each step", 0.0, **BOUNDED.fields()))
    phi, theta, psi = (float(a) for a in quat_to_euler_zyz(b.q0))
    V += [Variable("phi", "output", "continuous", "Real", "rad", "ZYZ precession angle, unwrapped", phi),
          Variable("theta", "output", "continuous", "Real", "rad", "ZYZ nutation angle in [0, pi]", theta),
          Variable("psi", "output", "continuous", "Real", "rad", "ZYZ spin angle, unwrapped", psi)]
    for n in ("L_x", "L_y", "L_z"):
        V.append(Variable(n, "output", "continuous", "Real", "kg.m2/s",
                          f"world-frame angular momentum about the reference point, {n[-1]}", None))
    V.append(Variable("energy", "output", "continuous", "Real", "J",
                      "kinetic plus potential energy 0.5*omega.I.omega + mass*g*cm_distance*(R e3).z", None))
    V.append(Variable("energy_error", "output", "continuous", "Real", "J",
                      "work-energy balance E(t) - E(0) - W_torque(t) + W_damping(t); 0 for the exact flow", None))
    return {v.name: v for v in V}


def _energy_error(y: np.ndarray, p: np.ndarray) -> float:
    """The energy_error output of one body's state y (GS_NY) with parameters p (J)."""
    out = np.empty((1, len(OUTPUT_NAMES)))
    _engine.outputs(y.reshape(1, -1), p.reshape(1, -1), out)
    return float(out[0, -1])



def _slots(variables: dict[str, Variable]) -> dict[str, tuple]:
    """Where each variable lives in a Model: (kind, index) by name."""
    slots = {}
    for name, var in variables.items():
        if var.causality == "output":
            slots[name] = (0, OUTPUT_NAMES.index(name))
        elif name in ("I1", "I2", "I3"):
            slots[name] = (1, int(name[1]) - 1)
        elif name in ("tau_x", "tau_y", "tau_z"):
            slots[name] = (2, "xyz".index(name[-1]))
        elif name in _BODY_ARRAYS:
            slots[name] = (3, _BODY_ARRAYS[name])
        else:
            slots[name] = (4, name)
    return slots


#: Per-body scalar parameters and the attribute holding each one's (n_bodies,) array.
_BODY_ARRAYS = {"mass": "_mass", "cm_distance": "_cm", "g": "_g", "damping": "_damping"}

#: The parameter arrays of a Model (shared with its scene's start values until set: Model._own).
_PARAM_ARRAYS = ("_moments", "_mass", "_cm", "_g", "_damping", "_tau")

_LAYOUT: dict[int, tuple[Scene, dict[str, Variable], dict[str, tuple]]] = {}


def _moments_plainly_valid(moments: np.ndarray) -> bool:
    """Every row finite, > 0 and within the triangle inequality (as :func:`check_principal_moments` has it)."""
    if moments.shape[0] == 1:
        a, b, c = moments[0].tolist()
        if not (0 < a < math.inf and 0 < b < math.inf and 0 < c < math.inf):
            return False
        k = 1.0 - TRIANGLE_RTOL
        return a + b >= c * k and a + c >= b * k and b + c >= a * k
    with np.errstate(all="ignore"):
        others = moments[:, [1, 2, 0]] + moments[:, [2, 0, 1]]
        return bool(np.all((moments > 0) & (moments < math.inf) & (others >= moments * (1.0 - TRIANGLE_RTOL))))


def _layout(scene: Scene) -> tuple:
    """variables_for(scene) for body 0, their slots, the scene's start arrays, the body names and their index, and
    the engine parameters of the start values (None when they do not pass :meth:`Model.initialize`'s checks, which
    then names what is wrong), computed once per scene object (scenes are frozen).

    The start arrays come in two kinds: the parameter arrays (``_moments``, ``_mass``, ``_cm``, ``_g``,
    ``_damping``, ``_tau``: read-only, shared by every model of the scene until it sets one, :meth:`Model._own`)
    and the state arrays (``_y``, ``_hint``, ``_stats``, ``_ex``, ``_status``: copied by each model)."""
    hit = _LAYOUT.get(id(scene))
    if hit is None or hit[0] is not scene:
        if len(_LAYOUT) > 64:
            _LAYOUT.clear()
        variables = variables_for(scene)
        bs = scene.bodies
        n = len(bs)
        y = np.zeros((n, _engine.NY))
        y[:, 0:4] = [b.q0 for b in bs]
        y[:, 4:7] = [b.omega0 for b in bs]
        params = {"_moments": np.array([b.moments for b in bs], dtype=float).reshape(n, 3),
                  "_mass": np.array([b.mass for b in bs], dtype=float),
                  "_cm": np.array([b.cm_distance for b in bs], dtype=float),
                  "_g": np.full(n, scene.g if scene.gravity else 0.0),
                  "_damping": np.array([b.damping for b in bs], dtype=float),
                  "_tau": np.zeros((n, 3))}
        for a in params.values():
            a.flags.writeable = False
        states = (y, np.zeros(n), np.zeros((n, 3), dtype=np.int64),
                  np.zeros((n, _engine.EX_SIZE)),  # the exact integrator's anchor (EX_VALID = 0: none)
                  np.zeros(n, dtype=np.int32))
        names = scene.body_names
        ok = _moments_plainly_valid(params["_moments"]) and not (
            scene.gravity and np.any((params["_cm"] > 0) & ~(params["_mass"] > 0)))
        p = _params_of(params["_moments"], params["_mass"], params["_g"], params["_cm"], params["_damping"],
                       params["_tau"], scene.max_drift) if ok else None
        if p is not None:
            p.flags.writeable = False  # each model copies it (initialize)
        hit = (scene, variables, _slots(variables), params, states, names, {b: i for i, b in enumerate(names)}, p)
        _LAYOUT[id(scene)] = hit
    return hit[1:]


def _params_of(moments, mass, g, cm, damping, tau, max_drift) -> np.ndarray:
    """The engine's parameter rows (n, NP): I1..I3, mass*g*cm_distance, damping, tau, max_drift."""
    p = np.empty((len(moments), _engine.NP))
    p[:, 0:3] = moments
    p[:, 3] = mass * g * cm
    p[:, 4] = damping
    p[:, 5:8] = tau
    p[:, 8] = max_drift
    return p




class BodyKernel:
    """The one-body kernel's operations of a :class:`~gyrosim.model.Model` (``self`` is the model)."""

    #: what one row of the model's state is (Model.set_many's messages)
    SYSTEM = "body"

    #: the engine writes a lone body's result rows itself (``_engine.trajectory_select``: gyrosim.simulate)
    ROWS_DIRECT = True

    def setup(self) -> None:
        """The model's engine rows for the scene's independent bodies: the parameter arrays shared with the
        scene's start values until set (:meth:`_own`), the state arrays its own."""
        (self.variables, self._slots, params, (y, hint, stats, ex, status), self.body_names, self._index,
         self._p_start) = _layout(self.scene)
        self.n_bodies = len(self.body_names)
        self.__dict__.update(params)  # _moments, _mass, _cm, _g, _damping, _tau: shared until set (_own)
        self._y, self._hint, self._stats, self._ex, self._status = y.copy(), hint.copy(), stats.copy(), ex.copy(), \
            status.copy()
        self._outbuf = None  # the outputs' buffer, allocated at the first use

    def _replica(self):
        """A model in this one's state, for a model built from a scene with no parameter set and nothing
        initialised or run yet (:class:`gyrosim.trajectory.Run` keeps one per prepared run): its state arrays
        copied, the rest shared (the parameter arrays are the scene's, read-only and copied on write)."""
        d = self.__dict__.copy()
        d["_y"] = self._y.copy()
        d["_hint"] = self._hint.copy()
        d["_stats"] = self._stats.copy()
        d["_ex"] = self._ex.copy()
        d["_status"] = self._status.copy()
        m = object.__new__(type(self))
        m.__dict__ = d
        return m

    def _replicable(self) -> bool:
        """True when :meth:`_replica` makes a model indistinguishable from this one: a one-body-engine model with
        the scene's parameter arrays, not initialised and no outputs computed."""
        return (not self._initialized and self._out is None and self._outbuf is None
                and self._p_start is not None and not hasattr(self, "_p")
                and not any(getattr(self, k).flags.writeable for k in _PARAM_ARRAYS))

    def _own(self, attr: str) -> np.ndarray:
        """The parameter array ``attr`` (``_moments``, ``_mass``, ...) to write into: a new model shares the scene's
        start values (read-only) until it sets one; then it gets its own copy."""
        a = getattr(self, attr)
        if not a.flags.writeable:
            a = a.copy()
            setattr(self, attr, a)
        return a

    def _body(self, body) -> int | slice:
        if body is None:
            return slice(None)
        if isinstance(body, str):
            if body not in self._index:
                raise ConfigError("body", body, f"one of {', '.join(self.body_names[:10])}")
            return self._index[body]
        if isinstance(body, (int, np.integer)) and -self.n_bodies <= body < self.n_bodies:
            return int(body)
        raise ConfigError("body", body, f"a body index in [0, {self.n_bodies}) or a body name")

    def _named(self, name, body):
        """``(name, body)`` of a variable given by its full name: ``<body>.<name>`` in a scene of several bodies
        (the naming of FMUs, CSV columns and ``gyrosim.simulate``'s fields), or ``name`` with ``body`` as given."""
        if isinstance(name, str) and "." in name and self.n_bodies > 1:
            b, _, short = name.partition(".")
            if b not in self._index:
                raise ConfigError("variable", name, "a variable name, or <body>.<name> with a body of the scene "
                                  f"({', '.join(self.body_names[:10])})")
            return short, b
        return name, body

    def _var(self, name) -> Variable:
        v = self.variables.get(name)
        if v is None:
            raise ConfigError("variable", name, f"a variable of scene {self.scene.name!r}"
                              f"{did_you_mean(name, self.variables)}: "
                              + ", ".join(self.variables))
        return v

    def set(self, name: str, value, body=None) -> None:
        """Set a parameter, input or state start by variable name, for one body or (``body=None``) all.

        Raises
        ------
        ConfigError
            Unknown name, an output that is not a state, or a value that is not allowed (named with the rule).
        """
        name, body = BodyKernel._named(self, name, body)
        v = BodyKernel._var(self, name)
        i = BodyKernel._body(self, body)
        if name in _PARAM_NAMES:
            self._p_start = None  # the parameters are no longer the scene's start values
        if v.type == "String":
            if name == "integrator":
                self._set_integrator(value)
            return
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ConfigError(name, value, f"a real number in {v.unit or '1'}") from None
        if not math.isfinite(x):
            raise ConfigError(name, value, f"a finite number in {v.unit or '1'}")
        if not v.range.contains(x):
            raise ConfigError(name, value, v.range.text(v.unit))
        if name in ("I1", "I2", "I3"):
            self._check_positive(name, x)
            BodyKernel._own(self, "_moments")[i, int(name[1]) - 1] = x
            self._initialized = False
            self._ex[i, _engine.EX_VALID] = 0.0
        elif name in ("mass", "cm_distance", "g", "damping"):
            if x < 0 or (name == "mass" and x == 0):
                raise ConfigError(name, value, f"a number {'>' if name == 'mass' else '>='} 0 in {v.unit}")
            BodyKernel._own(self, _BODY_ARRAYS[name])[i] = x
            self._initialized = False
        elif name == "max_step":
            self._check_positive(name, x)
            self.max_step = x
        elif name == "max_drift":
            if x < 0:
                raise ConfigError(name, value, "a number >= 0 (0: the health monitor off)")
            self.max_drift = x
            if self._initialized:
                self._p[:, 8] = x
        elif name in ("tau_x", "tau_y", "tau_z"):
            k = "xyz".index(name[-1])
            BodyKernel._own(self, "_tau")[i, k] = x
            if self._initialized:
                self._p[i, 5 + k] = x
        elif name in STATE_NAMES:
            self._y[i, STATE_NAMES.index(name)] = x
            self._state_dirty = True
            self._ex[i, _engine.EX_VALID] = 0.0
            self._out = None
        else:
            raise ConfigError(name, value, "a parameter, an input or a state start (q_*, omega_*); "
                              f"{name} is a derived output")

    def _assign_many(self, name: str, v: Variable, x: np.ndarray) -> None:
        """One value per body (Model.set_many checked the name and the shape): the first value that is not
        allowed raises as ``set`` would for its body."""
        with np.errstate(invalid="ignore"):
            if name in ("I1", "I2", "I3", "mass"):
                ok = x > 0
            elif name in ("cm_distance", "g", "damping"):
                ok = x >= 0
            else:
                ok = np.ones(x.shape, dtype=bool)
            ok &= np.isfinite(x) & v.range.contains(x)
        if not ok.all():
            b = int(np.flatnonzero(~ok)[0])
            self.set(name, float(x[b]), body=b)  # raises with set's message
        if name in _PARAM_NAMES:
            self._p_start = None
        if name in ("I1", "I2", "I3"):
            BodyKernel._own(self, "_moments")[:, int(name[1]) - 1] = x
            self._initialized = False
            self._ex[:, _engine.EX_VALID] = 0.0
        elif name in _BODY_ARRAYS:
            BodyKernel._own(self, _BODY_ARRAYS[name])[:] = x
            self._initialized = False
        elif name in ("tau_x", "tau_y", "tau_z"):
            k = "xyz".index(name[-1])
            BodyKernel._own(self, "_tau")[:, k] = x
            if self._initialized:
                self._p[:, 5 + k] = x
        elif name in STATE_NAMES:
            self._y[:, STATE_NAMES.index(name)] = x
            self._state_dirty = True
            self._ex[:, _engine.EX_VALID] = 0.0
            self._out = None
        else:
            raise ConfigError(name, "an array", "a parameter, an input or a state start (q_*, omega_*); "
                              f"{name} is a derived output")

    def get(self, name: str, body=0):
        """Value of a variable (float, or str for ``integrator``) of one body (``<body>.<name>``: that body's)."""
        name, body = BodyKernel._named(self, name, body)
        slot = self._slots.get(name)
        if slot is None:
            BodyKernel._var(self, name)  # raises with the names this scene has
        i = body if (type(body) is int and 0 <= body < self.n_bodies) else BodyKernel._body(self, body)
        kind, k = slot
        if kind == 0:
            return float(self._outputs_array()[i, k])
        if kind == 1:
            return float(self._moments[i, k])
        if kind == 2:
            return float(self._tau[i, k])
        if kind == 3:
            return float(getattr(self, k)[i])
        return self.integrator if name == "integrator" else float(getattr(self, name))

    def outputs(self, body=0) -> dict[str, float]:
        """Every output of one body by name."""
        row = self._outputs_array()[BodyKernel._body(self, body)]
        return {n: float(row[k]) for k, n in enumerate(OUTPUT_NAMES)}

    def outputs_array(self) -> np.ndarray:
        """(n_bodies, 15) outputs in the order of :data:`OUTPUT_NAMES` (a copy)."""
        return self._outputs_array().copy()

    def parameters(self, body=0) -> dict:
        """Current parameters of one body by name."""
        return {n: self.get(n, body) for n, v in self.variables.items() if v.causality == "parameter"}

    def inputs(self, body=0) -> dict[str, float]:
        """Current inputs of one body by name (empty when the scene has no torque inputs)."""
        return {n: self.get(n, body) for n, v in self.variables.items() if v.causality == "input"}

    # ----------------------------------------------------------------------------------------------- stepping
    def _params(self) -> np.ndarray:
        return _params_of(self._moments, self._mass, self._g, self._cm, self._damping, self._tau, self.max_drift)

    def initialize(self) -> None:
        """Validate parameters and the initial state; done by the first step (FMI: exit initialisation).

        Raises
        ------
        ConfigError
            Moments breaking the triangle inequality, a non-unit quaternion (|q| not within 1e-6 of 1), ...
        """
        p_old = getattr(self, "_p", None) if not self._state_dirty else None  # parameters changed during a run
        if not self._initialized and self._p_start is not None:  # the scene's start values, checked once
            self._p = self._p_start.copy()
            self._initialized = True
        if not self._initialized:
            if not _moments_plainly_valid(self._moments):  # the detailed check names the rule that failed
                for b in range(self.n_bodies):
                    check_principal_moments(*self._moments[b],
                                            where=None if self.n_bodies == 1 else f"body {self.body_names[b]!r}")
            if self.scene.gravity:
                bad = np.flatnonzero((self._cm > 0) & ~(self._mass > 0))
                if bad.size:
                    b = int(bad[0])
                    raise ConfigError("mass", float(self._mass[b]), "a number > 0",
                                      where=None if self.n_bodies == 1 else f"body {self.body_names[b]!r}")
            self._initialized = True
            self._p = BodyKernel._params(self, )
            if p_old is not None and p_old.shape == self._p.shape:  # the monitor follows (energy_error continuous)
                _engine.monitor_reparam(self._y, p_old, self._p)
        if self._state_dirty:
            b = _engine.start_state(self._y, self._p)  # q /= |q|; phi, psi from q (as the FMUs do), the health
            # monitor started; or the first bad row
            if b >= 0:
                q, w = self._y[b, 0:4].tolist(), self._y[b, 4:7].tolist()
                nq = math.sqrt(sum(v * v for v in q))
                if not abs(nq - 1.0) <= 1e-6:
                    raise ConfigError("q", q, "a unit quaternion (q_w, q_x, q_y, q_z) with |q| = 1 within 1e-6; its "
                                      f"norm is {nq:.9g}")
                raise ConfigError("omega", w, "finite rates in rad/s")
            self._state_dirty = False
            self._out = None

    def _torque(self) -> str | None:
        """Why 'exact' does not apply to a body now, or None: it solves a torque-free body and a Lagrange top
        (I1 = I2 within round-off, on a pivot, gravity the only torque: gs_exact_applies); the message names the
        torque (and, for gravity, the asymmetry)."""
        p, sc = self._p, self.scene
        flags = sc.flags
        for b in range(self.n_bodies):
            if _engine.exact_applies(flags, p[b]):
                continue
            where = f" of body {self.body_names[b]!r}" if self.n_bodies > 1 else ""
            terms = (((4, "damping", "N*m*s/rad"),) if sc.damping else ()) + \
                (((5, "tau_x", "N*m"), (6, "tau_y", "N*m"), (7, "tau_z", "N*m")) if sc.torque else ())
            for col, what, unit in terms:  # the terms that no exact flow carries
                if p[b, col] != 0.0:
                    return f"{what}{where} = {p[b, col]:.6g} {unit}"
            # gravity on a body that is not a Lagrange top
            return (f"mass*g*cm_distance{where} = {p[b, 3]:.6g} N*m on a body with I1 = {p[b, 0]:.6g} and "
                    f"I2 = {p[b, 1]:.6g} kg*m^2 (not a symmetric top)")
        return None

    def _check_call(self, h: float, what: str) -> None:
        """Refuse at once a call the engine would refuse: more internal steps than one call may take, or
        'exact' on a body that is not torque-free."""
        if self.integrator == "exact":
            torque = BodyKernel._torque(self, )
            if torque is not None:
                raise ConfigError("integrator", "exact", "a torque-free body or a Lagrange top (I1 = I2, on a pivot, "
                                  "gravity the only torque): 'exact' solves those flows, "
                                  f"and {torque} now; set it to 0 or choose another integrator ('adaptive', "
                                  "'dop853', 'rk4', 'splitting')")
        elif _engine.substeps(h, self.max_step) == 0:
            self._refuse_work(h, what)

    def _step_engine(self, h: float, t: float) -> None:
        method = _METHOD_CODES[self.integrator]
        single = self.n_bodies == 1  # one body: the engine itself leaves the row untouched on failure
        saved = None if single else (self._y.copy(), self._hint.copy(), self._stats.copy(), self._ex.copy())
        status = self._status
        failed = _engine.advance(method, self.scene.flags, self._y, self._p, t, h, self.tolerance, self.tolerance,
                                 self.max_step, self._hint, self._stats, self._ex, status, 0)
        if failed:
            b = int(np.flatnonzero(status)[0])
            k = int(status[b])
            status[:] = 0
            if not single:
                self._y, self._hint, self._stats, self._ex = saved
            start = (self._y, self._hint, self._stats, self._ex)
            n_sub = _engine.substeps(h, self.max_step)
            at = f" at internal step {k} of {n_sub}" if self.integrator in _FIXED and n_sub > 1 else ""
            where = f"the step from t = {t!r} s with h = {h!r} s"
            raise IntegrationError(BodyKernel._blowup(self, b, start, t, h, 0, 1, where, at=at))

    # ----------------------------------------------------------------------------------------------- blow-ups
    def _rerun(self, b: int, start: tuple, t: float, dt: float, k0: int, k: int, rows: np.ndarray | None):
        """What body ``b`` did in the interval that failed, again with the health monitor off: the state before
        that interval, the state after it (None when it fails again) and the drifts there.

        ``start`` holds (y, hint, stats, ex) of every body. In step mode (``step``, :meth:`step`) and for
        fixed-step methods and ``exact`` the rerun starts from the failing interval itself, at ``t + k0*dt``: one
        interval of ``dt``, the same bits as the failed one. ``adaptive`` and ``dop853`` trajectories are not rerun
        (their steps span the output points of the whole call): the engine leaves the state that tripped the monitor
        in row ``k`` of their outputs, ``rows`` (the body's rows of the call), rebuilt here."""
        method = _METHOD_CODES[self.integrator]
        y, hint, stats, ex = (a[b:b + 1].copy() for a in start)
        p = self._p[b:b + 1].copy()
        p[:, 8] = 0.0
        status = np.zeros(1, dtype=np.int32)
        d = np.empty((1, _engine.NDRIFT))
        if rows is None:
            before = y[0].copy()
            t1, run, max_step = t + k0 * dt, dt, self.max_step
            n_sub = _engine.substeps(dt, self.max_step)
            if self.integrator in _FIXED and n_sub > 1:
                # where in the interval it failed: the interval again with the monitor on (the same bits); the
                # monitor looks within long intervals, so the rerun stops at the internal step that tripped it
                on = (y.copy(), hint.copy(), stats.copy(), ex.copy())
                _engine.advance(method, self.scene.flags, on[0], self._p[b:b + 1], t1, dt, self.tolerance,
                                self.tolerance, self.max_step, on[1], on[2], on[3], status, 1)
                k_sub = int(status[0])
                status[:] = 0
                if 0 < k_sub < n_sub:
                    max_step = dt / n_sub
                    run = k_sub * max_step
            if _engine.advance(method, self.scene.flags, y, p, t1, run, self.tolerance, self.tolerance, max_step,
                               hint, stats, ex, status, 1):
                return before, None, None
            _engine.drift(self.scene.flags, y, p, d)
            return before, y[0].copy(), d[0]
        before = y[0].copy()
        before[0:7] = rows[k - 1, 0:7]
        if not np.all(np.isfinite(rows[k, 0:7])):  # not the monitor: the step size collapsed, or the work limit
            return before, None, None
        after = y[0].copy()
        after[0:7] = rows[k, 0:7]
        after[10] = rows[k, 13] - rows[k, 14]  # the energy the balance expects: energy - energy_error
        _engine.drift(self.scene.flags, after.reshape(1, -1), p, d)
        return before, after, d[0]

    def _blowup(self, b: int, start: tuple, t: float, dt: float, k0: int, k: int, where: str,
                rows: np.ndarray | None = None, at: str = "") -> str:
        """The message for body ``b`` failing in interval ``k`` (1-based) of a run of ``dt`` (as :meth:`_rerun`):
        the time, the step, what drifted and by how much, and advice the user is not already following."""
        integ = self.integrator
        who = "" if self.n_bodies == 1 else f" for body {self.body_names[b]!r}"
        before, after, d = BodyKernel._rerun(self, b, start, t, dt, k0, k, rows)
        p = self._p[b]
        w = math.sqrt(float(before[4] ** 2 + before[5] ** 2 + before[6] ** 2))
        if integ in ("adaptive", "dop853") and after is None:
            cause = ("the adaptive step size fell below its minimum, or the step needed more than "
                     f"{_engine.MAX_WORK:,} internal steps (the solution may truly blow up, or the rates are beyond "
                     "double precision)")
        elif integ == "exact" and after is None and not w * dt <= 1e6:
            return (f"integrator 'exact' refused{who} {where}: the body turns by |omega|*h = {w * dt:.3g} rad in it, "
                    "more than the 1e6 rad one call may sample; take shorter steps")
        elif after is None:
            cause = f"the state became non-finite or overflowed (|omega| > {_engine.OMEGA_LIMIT:g} rad/s){at}"
        else:
            names = ("the energy balance", "|L|", "L_z", "L_3")
            i = int(np.nanargmax(d)) if not np.all(np.isnan(d)) else 0
            val = f"energy_error = {_energy_error(after, p):.4g} J" if i == 0 else None
            cause = (f"{names[i]} drifted by {d[i]:.3g} of its scale{at} ({val + '; ' if val else ''}"
                     f"max_drift = {self.max_drift:g}, the health monitor's bound)")
        return (f"integrator {integ!r} blew up{who} in {where}: {cause}; "
                + BodyKernel._advice(self, before, p, dt))

    def _advice(self, y: np.ndarray, p: np.ndarray, dt: float) -> str:
        """A max_step from the fastest rate in the state and the study's stability map, or another integrator."""
        integ = self.integrator
        alt = {"euler": "rk4", "rk4": "splitting", "splitting": "dop853", "splitting4": "dop853",
               "adaptive": "splitting", "dop853": "splitting", "exact": "dop853", "strang_exact": "dop853",
               "yoshida_exact": "dop853", "bm4_exact": "dop853", "bm6_exact": "dop853"}[integ]
        rate = _engine.fastest_rate(self.scene.flags, y, p)
        w = math.sqrt(float(y[4] ** 2 + y[5] ** 2 + y[6] ** 2))
        what = "|omega|" if rate <= w else "the nutation frequency I3*|omega_3|/sqrt(I1*I2) (or the pendulum's)"
        x_max = _engine.STABLE_X[_METHOD_CODES[integ]]
        if integ in ("adaptive", "dop853", "exact"):
            return f"loosen the tolerance, check the parameters, or try the integrator {alt!r}"
        n_sub = max(1, _engine.substeps(dt, self.max_step))
        h = dt / n_sub
        x = h * rate
        if not rate > 0:
            return (f"the body was at rest before the step; check the torques and parameters, or try the integrator "
                    f"{alt!r}")
        if x_max == math.inf:  # the exact-flow splittings: the spin does not bound their step, the torque does
            x_g = _engine.STABLE_X_GRAVITY[_METHOD_CODES[integ]]
            h_g = 0.5 * x_g / rate
            if self.scene.flags & _engine.GRAVITY and p[3] != 0.0 and h_g < h:  # gravity's kick: the map's tops
                return (f"the fastest rate in the state is {what} = {rate:.4g} rad/s, so h*rate = {x:.3g} with "
                        f"internal steps of {h:.4g} s, beyond {integ}'s stable h*rate <= {x_g:g} under gravity "
                        f"(docs/accuracy.md, the stability map's tops): use max_step <= {h_g:.3g} s, or the "
                        f"integrator {alt!r}")
            return (f"{integ}'s free part is exact at any step (internal steps of {h:.4g} s here); its step is bounded "
                    "by the torque's time scale: use a smaller max_step, check the torques and parameters, or try "
                    f"the integrator {alt!r}")
        if x_max == 0.0:
            x_rk4 = _engine.STABLE_X[_METHOD_CODES["rk4"]]
            return (f"the fastest rate in the state is {what} = {rate:.4g} rad/s, so h*rate = {x:.3g} with internal "
                    f"steps of {h:.4g} s; {integ}'s energy grows by a factor 1 + (h*rate)^2 every step at any step "
                    f"size: use the integrator 'rk4' with max_step <= {0.5 * x_rk4 / rate:.3g} s, or 'splitting'")
        h_rec = 0.5 * x_max / rate if rate > 0 else math.inf
        if h_rec < h:
            return (f"the fastest rate in the state is {what} = {rate:.4g} rad/s, so h*rate = {x:.3g} with internal "
                    f"steps of {h:.4g} s, beyond {integ}'s stable h*rate <= {x_max:g} (docs/accuracy.md, the "
                    f"stability map): use max_step <= {h_rec:.3g} s, or the integrator {alt!r}")
        return (f"h*rate = {x:.3g} ({what} = {rate:.4g} rad/s, internal steps of {h:.4g} s) is within {integ}'s "
                f"stable h*rate <= {x_max:g}: the parameters may make the motion truly grow; check them, or try the "
                f"integrator {alt!r}")

    def trajectory(self, dt: float, n: int, *, angles: bool = True, momentum: bool = True,
                   status: np.ndarray | None = None) -> np.ndarray:
        """Advance ``n`` output intervals of ``dt`` s in one call of the engine; the outputs at every point.

        Fixed-step integrators and ``exact`` give the bits of ``n`` calls of :meth:`step` with ``dt``; ``adaptive``
        and ``dop853`` take the steps their error control chooses over the whole run and interpolate the output
        points with their continuous extensions (a step is never cut by the output grid).

        ``angles=False`` leaves phi, theta, psi out (NaN): they cost most of an output row; ``momentum=False``
        leaves L_x, L_y, L_z, energy and energy_error out (NaN).

        ``status``: an (n_bodies,) int32 array to keep going when bodies blow up (sweeps): instead of raising, a
        failing body ``b`` gets ``status[b]`` = the output interval (1-based) in which it failed and NaN rows from
        there, its state stays as before that interval (``adaptive``, ``dop853``: as before the call), and the
        other bodies run to the end (0 in ``status``).

        Returns
        -------
        (n + 1, n_bodies, 15) ndarray
            Outputs in the order of :data:`OUTPUT_NAMES` at ``time + k*dt``, ``k = 0..n``.

        Raises
        ------
        StepError
            ``dt`` not finite or <= 0, ``n`` < 0, or the run would end after the stop time.
        IntegrationError
            A body blew up (without ``status``); the model keeps its state from before the call, and the error
            carries the rows computed before the failing interval (``error.rows``).
        """
        return self._trajectory(dt, n, angles, momentum, status, True)

    def _trajectory(self, dt, n, angles: bool, momentum: bool, status, restore: bool) -> np.ndarray:
        """:meth:`trajectory`; ``restore=False`` for a caller that drops the model when the run fails
        (:func:`gyrosim.simulate`): the state before the call is kept only where the message needs it."""
        keep_going = status is not None
        dt, n, t = self._start_run(dt, n, status, self.n_bodies)
        integrator = self.integrator
        method = _METHOD_CODES[integrator]
        erk = integrator == "adaptive" or integrator == "dop853"
        out = np.empty((n + 1, self.n_bodies, len(OUTPUT_NAMES)))
        saved = None if keep_going or not (restore or erk) else (self._y.copy(), self._hint.copy(),
                                                                 self._stats.copy(), self._ex.copy())
        if keep_going:
            status[:] = 0
        else:
            status = self._status  # zeros (set back after a failure)
        t_base, k0 = BodyKernel._clock(self, dt, t)
        failed = _engine.trajectory(method, self.scene.flags, self._y, self._p, t_base, dt, n, self.tolerance,
                                    self.tolerance, self.max_step, self._hint, self._stats, self._ex, status, 0, out,
                                    _want(angles, momentum),
                                    k0)
        if failed and not keep_going:
            b = int(np.flatnonzero(status)[0])
            k = int(status[b])
            status[:] = 0
            where = (f"the output interval from t = {t + (k - 1) * dt!r} s to {t + k * dt!r} s (interval {k} of {n}, "
                     f"step {k0 + k} from t = {t_base!r} s)")
            if erk:  # the state that tripped the monitor is in row k
                msg = BodyKernel._blowup(self, b, saved, t_base, dt, k0, k, where, rows=out[:, b])
            else:  # the engine left the failing body at the start of its failing interval
                start = (self._y, self._hint, self._stats, self._ex)
                msg = BodyKernel._blowup(self, b, start, t_base, dt, k0 + k - 1, 1, where)
            if saved is not None:
                self._y, self._hint, self._stats, self._ex = saved
            err = IntegrationError(msg)
            err.rows = out[:k]
            raise err
        if failed and erk:  # NaN from the failing interval on, as for the other methods
            for b in np.flatnonzero(status):
                out[status[b]:, b] = np.nan
        self._tick(t, dt, n)
        return out

    def _clock(self, dt: float, t: float) -> tuple[float, int]:
        """(t_base, k0) of a run of intervals of dt from t: the clock of a run of equal steps (t_base + n*h)
        continued as step() would, for the same bits."""
        return (self._t_base, self._n) if dt == self._h else (t, 0)

    def _trajectory_select(self, dt, n, cols: np.ndarray, t_row0: float, angles: bool, momentum: bool,
                           ready: bool = False):
        """One body's :meth:`_trajectory` straight into result rows (``_engine.trajectory_select``): ``(n + 1, 1 +
        len(cols))`` rows of the time ``t_row0 + k*dt`` and the outputs ``cols``, the bits of ``Run.pack`` of
        :meth:`_trajectory`'s rows; None where the run failed (the model is then left as the engine left it: the
        caller, :func:`gyrosim.simulate`, drops it and runs again the whole way for the error).

        ``ready``: also the engine call's arguments as they were before it, copied (``(head, tail)``: those before
        and after ``res``), for :func:`gyrosim.simulate` to run the same call again on copies of them."""
        dt, n, t = self._start_run(dt, n, None, 1)
        res = np.empty((n + 1, 1 + len(cols)))
        t_base, k0 = BodyKernel._clock(self, dt, t)
        want = _want(angles, momentum)
        head = (_METHOD_CODES[self.integrator], self.scene.flags, self._y, self._p, t_base, dt, n, self.tolerance,
                self.tolerance, self.max_step, self._hint, self._stats, self._ex, self._status, cols, t_row0)
        args = None
        if ready:
            args = (tuple(a.copy() if isinstance(a, np.ndarray) else a for a in head), (want, k0))
        failed = _engine.trajectory_select(*head, res, want, k0, True)
        if failed:
            self._status[:] = 0
            return None, None
        self._tick(t, dt, n)
        return res, args

    def _outputs_array(self) -> np.ndarray:
        if self._out is None:
            if not self._initialized or self._state_dirty:
                self.initialize()
            if self._outbuf is None:
                self._outbuf = np.empty((self.n_bodies, len(OUTPUT_NAMES)))
            _engine.outputs(self._y, self._p, self._outbuf)
            self._out = self._outbuf
        return self._out

    # ----------------------------------------------------------------------------------------------- state
    _BODY_ARRAYS = _BODY_ARRAYS

    _STATE_FIELDS = ("_moments", "_mass", "_cm", "_g", "_damping", "_tau", "_y", "_hint", "_stats", "integrator",
                     "max_step", "max_drift", "tolerance", "start_time", "stop_time", "_t_base", "_n", "_h",
                     "_initialized", "_state_dirty", "_ex")

    #: One-body integrators whose trajectory call gives the bits of a loop of :meth:`step` (adaptive and dop853 span
    #: the output points of a whole call with their own steps: with inputs they step per interval, as an FMU does).
    _SAME_BITS_AS_STEPS = ("euler", "rk4", "splitting", "splitting4", "exact")

    def trajectory_is_steps(self, dt: float | None = None) -> bool:
        """Whether :meth:`trajectory` over several output intervals (of any ``dt``) gives the bits of a loop of
        :meth:`step` with the integrator set (inputs held over intervals may then be applied a block of intervals at
        a time)."""
        return self.integrator in BodyKernel._SAME_BITS_AS_STEPS

    def input_names(self) -> list[str]:
        """The inputs by full name (``tau_x``; ``<body>.tau_x`` in a scene of several bodies)."""
        bare = [n for n, v in self.variables.items() if v.causality == "input"]
        return bare if self.n_bodies == 1 else [f"{b}.{n}" for b in self.body_names for n in bare]

    # ----------------------------------------------------------------------------------------------- the systems
    # What the analyses ask of any model (the tree kernel answers the same): how many independent systems it
    # steps (rows of its state), where each one's coordinates are in a state row, how to restart rows from new
    # coordinates, and the fastest rate in a row.
    def n_systems(self) -> int:
        """Independent systems the model steps, one state row each: the bodies of a one-body scene."""
        return self.n_bodies

    def coordinates(self) -> list[tuple[str, str, int]]:
        """A system's continuous coordinates: (variable name, coordinate, slot in its state row), in slot order;
        the names are a system's own (bare: each body of a one-body scene is a system)."""
        return [(n, n, k) for k, n in enumerate(STATE_NAMES)]

    def n_coords(self) -> int:
        """The state row's continuous coordinates (the slots after them are the monitor's)."""
        return len(STATE_NAMES)

    def _restart_rows(self, rows: np.ndarray, coords: np.ndarray) -> int:
        """Put systems ``rows`` at ``coords`` (their first n_coords slots) and start them there as a state is
        started (quaternions normalised, the monitor restarted); the other rows untouched. The first row that is
        not finite (an index into ``rows``), or -1."""
        y = self._y[rows].copy()
        y[:, :coords.shape[1]] = coords
        bad = _engine.start_state(y, np.ascontiguousarray(self._p[rows]))
        self._ex[rows, _engine.EX_VALID] = 0.0
        if bad < 0:
            self._y[rows] = y
            self._out = None
        return bad

    def drift_measure(self, out0: np.ndarray) -> tuple:
        """What the sweeps measure of each body's drift from its outputs at the start ``out0``: the scales of the
        energy (T0 + |mgl|) and of the angular momentum (the larger of |L0| and sqrt(2 I_max |mgl|): a body at rest
        on a pivot still swings), ``drifts(traj) -> (|energy_error|, | |L| - |L0| |)`` over a trajectory's rows, and
        the trajectory's options (the angles are not needed)."""
        I = self._moments
        mgl = np.abs(self._mass * self._g * self._cm) if self.scene.gravity else np.zeros(self.n_bodies)
        w0 = out0[:, 4:7]
        s_energy = 0.5 * np.einsum("bi,bi->b", I * w0, w0) + mgl
        L0 = np.sqrt(np.einsum("bi,bi->b", out0[:, 10:13], out0[:, 10:13]))
        s_L = np.maximum(L0, np.sqrt(2.0 * I.max(axis=1) * mgl))

        def drifts(traj):
            L = traj[1:, :, 10:13]
            return (np.fmax.reduce(np.abs(traj[1:, :, 14]), axis=0),
                    np.fmax.reduce(np.abs(np.sqrt(np.einsum("tbi,tbi->tb", L, L)) - L0), axis=0))

        return s_energy, s_L, drifts, {"angles": False}

    def gimbal_lock(self, y=None, system: int = 0) -> None:
        """None: independent bodies have no gimbals (their ZYZ angles' singularity is the outputs', not the
        dynamics')."""
        return None

    def _forget(self) -> None:
        """A new integrator: no step-size history, no exact anchor."""
        self._hint[:] = 0.0
        self._ex[:, _engine.EX_VALID] = 0.0

    def inert_bodies(self, system: int = 0) -> list:
        """None: a body of this kernel has principal moments > 0 (checked when it is initialised)."""
        return []

    def on_face(self, system: int = 0) -> list[str]:
        """None: this kernel has no contacts."""
        return []

    def specific_force(self, system: int = 0) -> np.ndarray:
        """(n_bodies, 3) (``system`` is the body's row here): a body of this kernel turns about a point at rest in
        the world (its pivot, or its centre of mass), so its origin does not accelerate: an accelerometer there reads
        -g, in the body's frame, held by the pivot (+g along the world's up), and 0 where there is no gravity."""
        from .core.rotations import quat_to_matrix

        if not (self.scene.flags & _engine.GRAVITY):
            return np.zeros((self.n_bodies, 3))
        R = quat_to_matrix(self._outputs_array()[:, _engine.O_Q:_engine.O_Q + 4])   # body -> world
        return self._g[:, None] * R[:, 2, :]   # R^T (0, 0, g): the world's up in the body frame, times g

    def dynamics_kernel(self, system: int = 0) -> str:
        return "rigid_body"

    def fastest_rate(self, system: int = 0) -> float:
        """The fastest rate (rad/s) in system ``system``'s state: the step-size scale of its dynamics."""
        return float(_engine.fastest_rate(self.scene.flags, self._y[system], self._p[system]))

    def _restored(self) -> None:
        """After set_state: the engine's parameter rows from the restored parameters."""
        self._p_start = None
        if self._initialized:
            self._p = BodyKernel._params(self, )

