"""Scenes: TOML files that declare bodies and the terms they need; validation and the embedded scenes.

A scene carries only what it declares: gravity only where a body has a pivot (``cm_distance``), damping only
where a body has ``damping``, torque inputs only with ``torque_input = true``. The model built from it has only
those terms' variables. ``load_scene(None)`` is the full model with every variable of fmu/README.md.

File format (every key optional unless said)::

    [scene]
    name = "my_scene"            # required in files
    description = "..."
    integrator = "rk4"           # euler, rk4, splitting, splitting4, adaptive, dop853, exact, strang_exact,
                                 # yoshida_exact, bm4_exact, bm6_exact
    max_step = 1e-3              # s
    max_drift = 0.02             # health monitor: relative drift of the invariants counted as a blow-up (0: off)
    tolerance = 1e-8             # relative and absolute tolerance of adaptive
    output_interval = 0.01       # s, default communication step of `gyrosim simulate`
    stop_time = 10.0             # s
    g = 9.81                     # m/s^2, used by pivoted bodies

    [scene.orbit]                # a tree on an orbit about a central body (scene_tree.orbit_from_dict)
    mu = 3.986004418e14          # m^3/s^2 (default: the Earth's)
    radius = 7.0e6               # m: a circular orbit of the tree's reference point; without it, the free roots'
                                 # Kepler orbits from their r, v (the world origin at the central body's centre)

    [[body]]
    name = "top"                 # default body, body_1, ...
    count = 1                    # replicate the body (fields of gyroscopes, Monte Carlo)
    inertia = { principal = [I1, I2, I3] }           # kg*m^2, about the pivot when cm_distance is given
    # or { tensor = [[Ixx, Ixy, Ixz], [...], [...]] } (symmetric matrix, its elements as InertiaTensor takes them;
    #    Ixy = -sum m x y; the body frame becomes its principal axes)
    # or { shape = "cylinder", mass = 1.0, radius = 0.1, height = 0.05 }  (sphere: radius; box: length, width,
    #    height) about the centre of mass, shifted to the pivot by the parallel-axis theorem
    mass = 0.5                   # kg (pivoted bodies)
    cm_distance = 0.05           # m, pivot to centre of mass along body +z: adds the gravity term
    damping = 0.0                # N*m*s: adds the viscous term
    torque_input = true          # adds the inputs tau_x, tau_y, tau_z
    attitude = { q = [w, x, y, z] }  or  { zyz = [phi, theta, psi] }           # rad
    rates = { omega = [w1, w2, w3] }  or  { zyz_rates = [phi_dot, theta_dot, psi_dot] }   # rad/s
    spread = { I = 0.01, omega = 0.001, seed = 1 }   # relative normal scatter across `count` copies
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import tomllib
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np

from .core import _engine
from .core.inertia import InertiaTensor, check_principal_moments
from .core.rotations import (
    as_quaternion,
    euler_zyz_rates_to_omega_body,
    euler_zyz_to_quat,
    matrix_to_quat,
    quat_multiply,
    quat_to_euler_zyz,
)
from .errors import ConfigError

__all__ = ["Scene", "BodySpec", "load_scene", "SceneNotFoundError", "EMBEDDED_SCENES", "INTEGRATORS", "scene_from_dict",
           "check_name", "MAX_NAME"]

EMBEDDED_SCENES = ("free_body", "heavy_top", "gyroscope", "gimbal_gyroscope", "spacecraft", "cmg_spacecraft",
                   "double_pendulum", "coupled_pendula", "satellite", "satellite_wheels", "mass_spring_chain",
                   "triatomic", "tippe_top", "eulers_disk", "rattleback", "top_on_floor", "rolling_coin",
                   "billiard_ball", "iftomm_a01", "iftomm_a02", "iftomm_a03", "iftomm_a04", "iftomm_a05",
                   "cmg_scissored")
#: The embedded scenes with contact (DESIGN 4b: shapes on bodies against the plane ``floor``).
CONTACT_SCENES = ("tippe_top", "eulers_disk", "rattleback", "top_on_floor", "rolling_coin", "billiard_ball")
#: The IFToMM multibody benchmark's problems A01-A05 (docs/study/iftomm_problems.md) and the geared CMG pair: the
#: scenes of DESIGN 4b's closed loops and gears (A01 and A05 are trees as the benchmark states them).
LOOP_SCENES = ("iftomm_a01", "iftomm_a02", "iftomm_a03", "iftomm_a04", "iftomm_a05", "cmg_scissored")
INTEGRATORS = ("euler", "rk4", "splitting", "splitting4", "adaptive", "dop853", "exact", "strang_exact",
               "yoshida_exact", "bm4_exact", "bm6_exact")
G_DEFAULT = 9.81

_SCENE_KEYS = ("name", "description", "integrator", "max_step", "max_drift", "tolerance", "output_interval",
               "stop_time", "g", "gravity", "orbit")
_BODY_KEYS = ("name", "count", "inertia", "mass", "cm_distance", "damping", "torque_input", "attitude", "rates",
              "spread")
_SHAPES = {"sphere": ("mass", "radius"), "cylinder": ("mass", "radius", "height"),
           "box": ("mass", "length", "width", "height")}


@dataclass(frozen=True)
class BodySpec:
    """One body of a scene, in its principal frame.

    Attributes
    ----------
    name : str
    moments : (3,) ndarray
        Principal moments I1, I2, I3 in kg*m^2 about the reference point.
    mass, cm_distance, damping : float
        kg, m, N*m*s.
    q0 : (4,) ndarray
        Initial attitude (w, x, y, z), body (principal) frame -> world.
    omega0 : (3,) ndarray
        Initial body angular velocity, rad/s.
    """

    name: str
    moments: np.ndarray
    mass: float = 0.0
    cm_distance: float = 0.0
    damping: float = 0.0
    q0: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    omega0: np.ndarray = field(default_factory=lambda: np.zeros(3))


@dataclass(frozen=True)
class Scene:
    """A validated scene: bodies, declared terms and integrator settings.

    Attributes
    ----------
    gravity, damping, torque : bool
        The terms the scene carries; the model drops the variables of the others.
    """

    name: str
    bodies: tuple[BodySpec, ...]
    gravity: bool = True
    damping: bool = True
    torque: bool = True
    integrator: str = "rk4"
    max_step: float = 1e-3
    max_drift: float = _engine.MAX_DRIFT
    tolerance: float = 1e-8
    output_interval: float = 0.01
    stop_time: float = 10.0
    g: float = G_DEFAULT
    description: str = ""
    source: str = "<embedded>"
    #: a tree scene (docs/trees.md): its bodies (core.tree.TreeBody), coupling springs (a, b, k), their names and
    #: the scene parameters that set body parameters (scene_tree.Alias); None for a scene of independent bodies
    tree: tuple | None = None
    couplings: tuple = ()
    coupling_names: tuple = ()
    aliases: tuple = ()
    #: copies of the tree a model of this scene holds (sweeps: one copy per sample, stepped in one engine call)
    systems: int = 1
    #: a tree's orbit about a central body (core.tree.Orbit, ``[scene.orbit]``), or None
    orbit: object | None = None
    #: a tree's elements: springs between bodies (core.tree.Spring) and force inputs (core.tree.Force)
    springs: tuple = ()
    forces: tuple = ()
    #: a tree's contact: convex shapes on bodies (core.tree.Shape) and planes in the world (core.tree.Plane)
    shapes: tuple = ()
    planes: tuple = ()
    #: a tree's closed loops (core.tree.Loop) and gears (core.tree.Gear), scene_loops
    loops: tuple = ()
    gears: tuple = ()
    #: gravity's direction (unit, world; g is its magnitude): -z unless the scene's ``gravity`` turns it
    gravity_dir: tuple = (0.0, 0.0, -1.0)

    def element_variables(self) -> dict:
        """The elements' variables by full name -> ``(kind, element index, short name)``: a spring's parameters
        ``<spring>.stiffness``, ``.rest_length``, ``.damping``; a force's inputs ``<body>.<force>.f_x..z``."""
        out = {}
        for e, sp in enumerate(self.springs):
            for k in ("stiffness", "rest_length", "damping"):
                out[f"{sp.name}.{k}"] = ("spring", e, k)
        for e, f in enumerate(self.forces):
            for c in "xyz":
                out[self.var_name(self.tree[f.body].name, f"{f.name}.f_{c}")] = ("force", e, f"f_{c}")
        if self.shapes:
            from .scene_contact import plane_parameters

            for e, pl in enumerate(self.planes):
                for k in plane_parameters(pl):
                    out[f"{pl.name}.{k}"] = ("plane", e, k)
        for e, gr in enumerate(self.gears):
            out[f"{gr.name}.ratio"] = ("gear", e, "ratio")
        return out

    def loop_outputs(self) -> tuple:
        """The closed loops' and the gears' output names (``<loop>.residual``, ``<gear>.torque``, ...): scene-wide,
        never with a body's prefix."""
        from .core.tree import GEAR_OUTPUTS, LOOP_OUTPUTS

        return tuple(f"{lp.name}.{c}" for lp in self.loops for c in LOOP_OUTPUTS) + \
            tuple(f"{gr.name}.{c}" for gr in self.gears for c in GEAR_OUTPUTS)

    def contact_outputs(self) -> tuple:
        """The contacts' output names (``<shape>.gap``, ...; kernel_tree.contact_stems): scene-wide, like the
        elements' variables, though named with a body's prefix in scenes of several bodies."""
        if not self.shapes:
            return ()
        from .core.tree import CONTACT_OUTPUTS
        from .kernel_tree import contact_stems

        return tuple(self.var_name(self.tree[h.body].name, f"{stem}.{c}") for h, stem in contact_stems(self)
                     for c in CONTACT_OUTPUTS)

    @property
    def kernel(self) -> str:
        """The engine kernel picked for this system at set-up (docs/trees.md): ``"body"`` (Euler's equations in
        closed form, the exact flows and splittings; independent bodies) or ``"tree"`` (the articulated-body
        algorithm). Every feature that depends on it asks :attr:`integrators`, :meth:`variables` and the engine
        description rather than the kernel's name."""
        return "body" if self.tree is None else "tree"

    @property
    def flags(self) -> int:
        """Engine term flags (GRAVITY | DAMPING | TORQUE)."""
        return ((_engine.GRAVITY if self.gravity else 0) | (_engine.DAMPING if self.damping else 0)
                | (_engine.TORQUE if self.torque else 0))

    @property
    def body_names(self) -> list[str]:
        return [b.name for b in (self.tree if self.tree is not None else self.bodies)]

    @property
    def integrators(self) -> tuple[str, ...]:
        """The integrators this system takes, from the kernel picked for it at set-up (docs/trees.md): every
        integrator on the one-body kernel (Euler's equations, its exact flows and splittings), the Runge-Kutta
        methods on the articulated-body algorithm."""
        if self.tree is None:
            return INTEGRATORS
        from .scene_tree import implicit_fits, split_fits

        out = TREE_INTEGRATORS if implicit_fits(self.tree, self.orbit, bool(self.shapes)) else tuple(
            m for m in TREE_INTEGRATORS if m not in ("midpoint", "energy_momentum"))
        return out if split_fits(self) else tuple(m for m in out if m not in ("splitting", "splitting4"))

    def variables(self) -> dict:
        """Every variable of the scene by its full name (name -> ``model.Variable``), under :meth:`var_name`'s
        rule: the one table that the model, ``gyrosim info``, the FMU builder, the service and the sweep read."""
        if self.tree is not None:
            from .kernel_tree import tree_variables

            return tree_variables(self)
        from .kernel_body import variables_for

        if len(self.bodies) == 1:
            return variables_for(self)
        out = {}
        for b, body in enumerate(self.bodies):  # independent bodies: each one's whole table under its name
            out.update({f"{body.name}.{n}": v for n, v in variables_for(self, b).items()})
        return out

    @property
    def kernel_description(self) -> str:
        """The kernel picked for the system, in words (``gyrosim info``)."""
        if self.tree is None:
            return "Euler's equations in closed form, with the exact flows and the splittings"
        from .scene_tree import tree_kernel

        return {"gyrostat": "a gyrostat (a hub carrying rotor wheels) in closed form",
                "gimbal": "a rotor in two gimbals in closed form"}.get(tree_kernel(self),
                                                                       "the articulated-body algorithm")

    def state_names(self) -> list[str]:
        """The continuous coordinates by full name: the outputs whose start values a user sets (the quaternion
        and rates of a body; a tree's joint coordinates and a circular orbit's anomaly)."""
        if self.tree is None:
            from .kernel_body import STATE_NAMES

            return [self.var_name(b, n) for b in self.body_names for n in STATE_NAMES]
        return [n for n, v in self.variables().items() if v.causality == "output" and v.start is not None]

    @property
    def n_systems(self) -> int:
        """Independent systems a model of the scene steps: the bodies of the one-body kernel (each its own
        system), or the copies of a tree (``systems``)."""
        return len(self.bodies) if self.tree is None else self.systems

    def output_names(self) -> list[str]:
        """The columns of the engine's output rows (a trajectory's fields after ``time``), by full name."""
        if self.tree is not None:
            from .kernel_tree import tree_output_names

            return tree_output_names(self)
        from .kernel_body import OUTPUT_NAMES

        if len(self.bodies) == 1:
            return list(OUTPUT_NAMES)
        return [f"{b.name}.{o}" for b in self.bodies for o in OUTPUT_NAMES]

    def replicated(self, k: int) -> Scene:
        """The scene with ``k`` copies of its systems, stepped in one engine call (sweeps: a copy per sample;
        chaos: a neighbour per reference): a tree's ``systems`` times k, a one-body scene's bodies k times (the
        j-th copy of body ``b`` named ``b~j``, the first keeping its name)."""
        if self.tree is not None:
            return dataclasses.replace(self, systems=self.systems * k)
        bodies = tuple(dataclasses.replace(b, name=f"{b.name}~{j}" if j else b.name)
                       for j in range(k) for b in self.bodies)
        return dataclasses.replace(self, bodies=bodies)

    def describe(self) -> tuple[str, list[str]]:
        """What ``gyrosim info`` says of the system: its bodies (with their joints in a tree) and its terms."""
        if self.tree is None:
            names = ", ".join(self.body_names[:10]) + (", ..." if len(self.body_names) > 10 else "")
            return names, [t for t, on in (("gravity", self.gravity), ("damping", self.damping),
                                           ("torque inputs", self.torque)) if on]
        names = ", ".join(f"{b.name} ({b.joint} on {self.tree[b.parent].name if b.parent >= 0 else 'world'})"
                          for b in self.tree)
        orbit = ("gravity gradient on a circular orbit" if getattr(self.orbit, "circular", False)
                 else "gravity gradient and central force on Kepler orbits")
        return names, [t for t, on in (("gravity", self.g > 0), ("joint damping", self.damping),
                                       ("motor and torque inputs", self.torque),
                                       ("springs", bool(self.couplings) or bool(self.springs) or
                                        any(b.stiffness > 0 or np.any(b.ball_stiffness > 0) for b in self.tree)),
                                       ("joint stops", any(b.lower is not None or b.upper is not None
                                                           for b in self.tree)),
                                       ("force inputs", bool(self.forces)),
                                       ("contact (" + ", ".join(f"{h.name} on {h.kind}" for h in self.shapes) +
                                        " against " + ", ".join(p.name for p in self.planes) + ")",
                                        bool(self.shapes) and bool(self.planes)),
                                       ("closed loops (" + ", ".join(f"{lp.name} {lp.kind}" for lp in self.loops) +
                                        ")", bool(self.loops)),
                                       ("gears (" + ", ".join(f"{gr.name} {self.tree[gr.a].name}:"
                                                              f"{self.tree[gr.b].name}" for gr in self.gears) + ")",
                                        bool(self.gears)),
                                       (orbit, self.orbit is not None)) if on]

    def to_dict(self) -> dict:
        """The system as JSON-able data (a sweep's Parquet metadata ``gyrosim.scene``): its settings and bodies."""
        head = {"name": self.name, "source": self.source, "description": self.description}
        if self.tree is not None:
            return {**head, "integrator": self.integrator, "max_step": self.max_step, "max_drift": self.max_drift,
                    "tolerance": self.tolerance, "output_interval": self.output_interval,
                    "stop_time": self.stop_time, "g": self.g,
                    "tree": [{"name": b.name, "parent": b.parent, "joint": b.joint,
                              "pos": [float(x) for x in b.pos], "axis": [float(x) for x in b.axis],
                              "mass": float(b.mass), "cm": [float(x) for x in b.cm],
                              "inertia": [float(x) for x in np.asarray(b.inertia).ravel()]} for b in self.tree],
                    "couplings": [list(c) for c in self.couplings],
                    "gravity_dir": [float(x) for x in self.gravity_dir],
                    "springs": [{"name": e.name, "a": e.a, "point_a": [float(x) for x in e.point_a], "b": e.b,
                                 "point_b": [float(x) for x in e.point_b], "stiffness": e.stiffness,
                                 "rest_length": e.rest_length, "damping": e.damping} for e in self.springs],
                    "forces": [{"name": f.name, "body": f.body, "point": [float(x) for x in f.point],
                                "world": f.world} for f in self.forces],
                    "shapes": [{"name": h.name, "body": h.body, "kind": h.kind,
                                "center": [float(x) for x in h.center],
                                "axes": [float(x) for x in np.asarray(h.axes).ravel()],
                                "dims": [float(x) for x in h.dims]} for h in self.shapes],
                    "planes": [{k: (v.tolist() if isinstance(v, np.ndarray) else v)
                                for k, v in dataclasses.asdict(p).items()} for p in self.planes],
                    "loops": [{"name": lp.name, "a": lp.a, "b": lp.b, "kind": lp.kind,
                               **{k: [float(x) for x in getattr(lp, k)] for k in ("point_a", "point_b", "axis_a",
                                                                                  "axis_b", "q0")}}
                              for lp in self.loops],
                    "gears": [{"name": gr.name, "a": gr.a, "b": gr.b, "ratio": float(gr.ratio)} for gr in self.gears]}
        b = self.bodies[0]
        return {**head, "gravity": self.gravity, "damping": self.damping, "torque": self.torque,
                "integrator": self.integrator, "max_step": self.max_step, "max_drift": self.max_drift,
                "tolerance": self.tolerance, "output_interval": self.output_interval, "stop_time": self.stop_time,
                "g": self.g,
                "body": {"name": b.name, "moments": [float(x) for x in b.moments], "mass": float(b.mass),
                         "cm_distance": float(b.cm_distance), "damping": float(b.damping),
                         "q0": [float(x) for x in b.q0], "omega0": [float(x) for x in b.omega0]}}

    def var_name(self, body: str, short: str) -> str:
        """A body's variable under the one naming rule (docs/trees.md): bare in a scene of one body, whatever its
        joint and whichever syntax declared it (``v_x`` for a ``free`` body); ``<body>.<name>`` with several."""
        return short if len(self.body_names) == 1 else f"{body}.{short}"

    def split_name(self, name: str) -> tuple[int | None, str]:
        """The body (its index) and short name of a tree's variable ``name``; ``(None, name)`` for a scene-wide
        one (``energy``, ``g``, a scene parameter). The inverse of :meth:`var_name`.

        Raises
        ------
        ValueError
            ``<body>.<name>`` with a body that is not the scene's.
        """
        from .scene_tree import BODY_VARIABLES

        body, _, short = name.rpartition(".")
        names = self.body_names
        if body and body not in names and (name in self.element_variables() or name in self.contact_outputs()
                                           or name in self.loop_outputs()):
            return None, name
        if body:
            return names.index(body), short
        if len(names) == 1 and short in BODY_VARIABLES:
            return 0, short
        return None, short

    @property
    def torque_free(self) -> bool:
        """True when no term can exert a torque (gravity, damping and inputs all absent)."""
        return not (self.gravity or self.damping or self.torque)

    def exact_start(self) -> str | None:
        """None when ``exact`` applies to every body at the start (torque-free, or a Lagrange top: I1 = I2 on a
        pivot, gravity the only torque), else why not (for a message)."""
        for b in self.bodies:
            where = f" (body {b.name!r})" if len(self.bodies) > 1 else ""
            if self.damping and b.damping != 0.0:
                return f"damping = {b.damping:.6g} N*m*s/rad{where}"
            mgl = b.mass * self.g * b.cm_distance if self.gravity else 0.0
            I1, I2 = float(b.moments[0]), float(b.moments[1])
            if mgl != 0.0 and abs(I1 - I2) > 4 * 2.220446049250313e-16 * max(I1, I2):
                return (f"mass*g*cm_distance = {mgl:.6g} N*m on a body that is not symmetric about its axis "
                        f"(I1 = {I1:.6g} != I2 = {I2:.6g}: not a Lagrange top){where}")
        return None

    def torque_free_start(self) -> str | None:
        """None when every body starts torque-free with its parameters (mass*g*cm_distance = 0 where there is
        gravity, damping = 0; torque inputs start at 0), else what exerts a torque (for a message)."""
        for b in self.bodies:
            where = f" (body {b.name!r})" if len(self.bodies) > 1 else ""
            if self.gravity and b.mass * self.g * b.cm_distance != 0.0:
                return f"mass*g*cm_distance = {b.mass * self.g * b.cm_distance:.6g} N*m{where}"
            if self.damping and b.damping != 0.0:
                return f"damping = {b.damping:.6g} N*m*s/rad{where}"
        return None


def did_you_mean(word, allowed, cutoff: float = 0.6) -> str:
    """``" (did you mean 'x'?)"`` for the closest of ``allowed`` to ``word``, or ``""``."""
    close = difflib.get_close_matches(str(word), list(allowed), n=1, cutoff=cutoff)
    return f" (did you mean {close[0]!r}?)" if close else ""


class SceneNotFoundError(ConfigError):
    """A scene that is neither an embedded name nor a readable TOML file (the message says "not found")."""

    def __init__(self, scene: str, message: str):
        super().__init__("scene", scene, message)
        self.args = (message,)


def _suggest(key: str, allowed) -> str:
    return f"one of {', '.join(allowed)}{did_you_mean(key, allowed, cutoff=0.5)}"


def _plain(v):
    """A value as a message shows it: numpy scalars and arrays as Python numbers and lists."""
    if isinstance(v, np.ndarray):
        return v.tolist()
    if isinstance(v, np.generic):
        return v.item()
    return v


def _check_keys(table: dict, allowed, where: str):
    for k in table:
        if k not in allowed:
            raise ConfigError(k, table[k], f"a known key: {_suggest(k, allowed)}", where=where)


def _num(table, key, where, default=None, *, lo=None, lo_open=False, required=False):
    if key not in table:
        if required:
            raise ConfigError(key, None, "a value (this key is required)", where=where)
        return default
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(key, v, "a number", where=where)
    v = float(v)
    if not math.isfinite(v):
        raise ConfigError(key, v, "a finite number", where=where)
    if lo is not None and (v < lo or (lo_open and v == lo)):
        raise ConfigError(key, v, f"a number {'>' if lo_open else '>='} {lo}", where=where)
    return v


#: The smallest relative tolerance a scene or a command may give the adaptive integrators: double precision (eps =
#: 2.2e-16) cannot meet less (a step's round-off alone is a few eps).
MIN_TOLERANCE = 1e-15


def _tolerance(table, where) -> float:
    v = _num(table, "tolerance", where, 1e-8)
    if not MIN_TOLERANCE <= v < 1.0:
        raise ConfigError("tolerance", v, f"a number from {MIN_TOLERANCE:g} to 1 (exclusive): double precision "
                          "cannot meet a smaller relative tolerance", where=where)
    return v


def _vec(table, key, n, where):
    v = table[key]
    if not isinstance(v, list) or len(v) != n or any(isinstance(x, bool) or not isinstance(x, (int, float))
                                                       for x in v):
        raise ConfigError(key, v, f"a list of {n} numbers", where=where)
    a = np.array(v, dtype=float)
    if not np.all(np.isfinite(a)):
        raise ConfigError(key, v, f"a list of {n} finite numbers", where=where)
    return a


def _one_of(table: dict, options, where):
    _check_keys(table, options, where)
    if len(table) != 1:
        raise ConfigError(where.rsplit(".", 1)[-1], table, f"exactly one of {', '.join(options)}", where=where)
    (k,) = table
    return k


def _inertia(spec, where, mass, cm_distance):
    """Return (principal moments, R_geom_principal) about the reference point."""
    if not isinstance(spec, dict):
        raise ConfigError("inertia", spec, "a table: {principal = [..]}, {tensor = [[..]]} or {shape = ..}",
                          where=where)
    w = f"{where}.inertia"
    if "shape" in spec:
        shape = spec["shape"]
        if not isinstance(shape, str) or shape not in _SHAPES:
            raise ConfigError("shape", shape, _suggest(str(shape), list(_SHAPES)), where=w)
        _check_keys(spec, ("shape",) + _SHAPES[shape], w)
        args = [_num(spec, k, w, required=True, lo=0.0, lo_open=(k in ("mass", "radius"))) for k in _SHAPES[shape]]
        I = getattr(InertiaTensor, shape)(*args)
        m_shape = args[0]
        if mass and abs(m_shape - mass) > 1e-12 * max(m_shape, mass):
            raise ConfigError("mass", mass, f"the shape's mass {m_shape} (or leave body.mass out)", where=where)
        if cm_distance:
            I = I.shifted(m_shape, [0.0, 0.0, cm_distance])
        return I.to_matrix().diagonal().copy(), np.eye(3), m_shape
    key = _one_of(spec, ("principal", "tensor"), w)
    if key == "principal":
        m = _vec(spec, "principal", 3, w)
        try:
            check_principal_moments(*m.tolist(), where=w)  # plain floats in the message, not np.float64(...)
        except ConfigError as e:
            raise ConfigError(f"principal ({e.field})", _plain(e.value), e.allowed, where=w) from None
        return m, np.eye(3), None
    T = spec["tensor"]
    if (not isinstance(T, list) or len(T) != 3 or any(not isinstance(r, list) or len(r) != 3 for r in T)):
        raise ConfigError("tensor", T, "a 3x3 list of lists in kg*m^2", where=w)
    try:
        It = InertiaTensor.from_matrix(np.array(T, dtype=float))
    except (ConfigError, ValueError, TypeError) as e:
        raise ConfigError("tensor", T, getattr(e, "allowed", str(e)), where=w) from None
    moments, axes = It.principal_axes()
    return moments, axes, None


def _attitude_rates(tbl: dict, where: str) -> tuple[np.ndarray, np.ndarray]:
    """A [[body]] table's start attitude (w, x, y, z; ``attitude = {q = ..}`` or ``{zyz = ..}``, identity by
    default) and body rates (rad/s; ``rates = {omega = ..}`` or ``{zyz_rates = ..}``, zero by default)."""
    q = np.array([1.0, 0.0, 0.0, 0.0])
    if "attitude" in tbl:
        a = tbl["attitude"]
        if not isinstance(a, dict):
            raise ConfigError("attitude", a, "a table {q = [w, x, y, z]} or {zyz = [phi, theta, psi]}", where=where)
        k = _one_of(a, ("q", "zyz"), f"{where}.attitude")
        v = _vec(a, k, 4 if k == "q" else 3, f"{where}.attitude")
        if k == "q":
            try:
                q = as_quaternion(v, "attitude.q")
            except ConfigError as e:
                raise ConfigError(e.field, e.value, e.allowed, where=where) from None
        else:
            q = euler_zyz_to_quat(*v)
    omega = np.zeros(3)
    if "rates" in tbl:
        r = tbl["rates"]
        if not isinstance(r, dict):
            raise ConfigError("rates", r, "a table {omega = [..]} or {zyz_rates = [..]}", where=where)
        k = _one_of(r, ("omega", "zyz_rates"), f"{where}.rates")
        v = _vec(r, k, 3, f"{where}.rates")
        if k == "omega":
            omega = v
        else:
            phi, theta, psi = quat_to_euler_zyz(q)
            omega = euler_zyz_rates_to_omega_body(phi, theta, psi, *v)
    return np.asarray(q, dtype=float), np.asarray(omega, dtype=float)


#: The longest scene or body name (characters): a scene's names its FMU's model identifier (a C identifier, the
#: FMU's and its binary's file names) and files such as ``<name>_out.csv``, a body's Zenoh keys, ROS 2 topics and
#: plot files; every file name stays far below the 255 bytes a file system allows and Windows' 260-character paths.
MAX_NAME = 64
#: Body names that mean something else: ``world`` is the frame every root hangs from (``parent = "world"``, the
#: ``frame_id`` of a root's transform).
RESERVED_BODY_NAMES = ("world",)


def check_name(name, where: str, kind: str = "scene") -> str:
    """A scene's (``kind="scene"``) or a body's (``"body"``) name: 1 to :data:`MAX_NAME` ASCII letters, digits,
    ``_`` and ``-``; a body's not ``world``. Returns the name.

    Raises
    ------
    ConfigError
        Naming the field ``name``, the value (a long one cut short, with its length) and what is allowed.
    """
    uses = ("it makes the FMU's model identifier, a C identifier, and file names such as <name>_out.csv"
            if kind == "scene" else "it is a Zenoh key, a ROS 2 topic name and a part of variable and file names")
    allowed = f"a name of 1 to {MAX_NAME} characters: ASCII letters, digits, '_' and '-' ({uses})"
    if not isinstance(name, str) or not name:
        raise ConfigError("name", name, allowed, where=where)
    if len(name) > MAX_NAME:
        raise ConfigError("name", f"{name[:24]}...{name[-8:]} ({len(name)} characters)", allowed, where=where)
    bad = sorted({c for c in name if not (c.isascii() and (c.isalnum() or c in "_-"))})
    if bad:
        raise ConfigError("name", name, f"{allowed}; it has {', '.join(map(repr, bad))}", where=where)
    if kind == "body" and name in RESERVED_BODY_NAMES:
        raise ConfigError("name", name, "a body name other than 'world': 'world' is the frame the roots hang from "
                          "(parent = \"world\" means it, and it is the frame_id of a root's transform)", where=where)
    return name


def _body(tbl: dict, index: int, scene_g: float, where: str) -> tuple[list[BodySpec], set[str]]:
    where = f"{where} body[{index}]"
    if not isinstance(tbl, dict):
        raise ConfigError("body", tbl, "a table ([[body]])", where=where)
    _check_keys(tbl, _BODY_KEYS, where)
    terms = set()
    name = check_name(tbl.get("name", "body" if index == 0 else f"body_{index}"), where, "body")
    count = tbl.get("count", 1)
    if isinstance(count, bool) or not isinstance(count, int) or count < 1 or count > 10_000_000:
        raise ConfigError("count", count, "an integer from 1 to 10,000,000", where=where)
    cm = _num(tbl, "cm_distance", where, 0.0, lo=0.0)
    mass = _num(tbl, "mass", where, None, lo=0.0, lo_open=True)
    if "cm_distance" in tbl:
        terms.add("gravity")
    if "inertia" not in tbl:
        raise ConfigError("inertia", None, "a table (this key is required)", where=where)
    moments, R_gp, shape_mass = _inertia(tbl["inertia"], where, mass, cm)
    if mass is None:
        mass = shape_mass if shape_mass is not None else 0.0
    if "gravity" in terms and mass <= 0:
        raise ConfigError("mass", tbl.get("mass"), "a number > 0 for a body with a pivot (cm_distance)",
                          where=where)
    damping = _num(tbl, "damping", where, 0.0, lo=0.0)
    if "damping" in tbl:
        terms.add("damping")
    ti = tbl.get("torque_input", False)
    if not isinstance(ti, bool):
        raise ConfigError("torque_input", ti, "true or false", where=where)
    if ti:
        terms.add("torque")
    # attitude in the frame the user described; converted to the principal frame
    q_geom, omega_geom = _attitude_rates(tbl, where)
    q0 = quat_multiply(q_geom, matrix_to_quat(R_gp)) if not np.allclose(R_gp, np.eye(3)) else q_geom
    omega0 = R_gp.T @ omega_geom
    spread = tbl.get("spread", {})
    if not isinstance(spread, dict):
        raise ConfigError("spread", spread, "a table {I = .., omega = .., seed = ..}", where=where)
    _check_keys(spread, ("I", "omega", "seed"), f"{where}.spread")
    sI = _num(spread, "I", f"{where}.spread", 0.0, lo=0.0)
    sw = _num(spread, "omega", f"{where}.spread", 0.0, lo=0.0)
    seed = spread.get("seed", 0)
    rng = np.random.default_rng(seed if isinstance(seed, int) else 0)
    bodies = []
    for i in range(count):
        m_i, w_i = moments, omega0
        if i > 0 and (sI or sw):
            m_i = moments * (1.0 + sI * rng.standard_normal(3))
            w_i = omega0 * (1.0 + sw * rng.standard_normal(3))
            try:
                check_principal_moments(*m_i, where=where)
            except ConfigError:
                m_i = moments
        bodies.append(BodySpec(name if count == 1 else f"{name}_{i}", np.array(m_i, dtype=float), float(mass),
                               float(cm), float(damping), np.array(q0, dtype=float), np.array(w_i, dtype=float)))
    return bodies, terms


def scene_from_dict(data: dict, source: str = "<dict>") -> Scene:
    """Validate a parsed scene (the TOML structure) and return a :class:`Scene`.

    Raises
    ------
    ConfigError
        Naming the source, the key, the value and what is allowed; unknown keys get a "did you mean".
    """
    _check_keys(data, ("scene", "body", "sweep", "coupling", "parameters", "spring", "force", "shape", "plane", "loop",
                       "gear"), source)
    # [sweep]: `gyrosim sweep`
    sc = data.get("scene", {})
    if not isinstance(sc, dict):
        raise ConfigError("scene", sc, "a table [scene]", where=source)
    where = f"{source} [scene]"
    _check_keys(sc, _SCENE_KEYS, where)   # [scene.orbit]: a tree's orbit (scene_tree.orbit_from_dict)
    name = check_name(sc.get("name"), where, "scene")
    integ = sc.get("integrator", "rk4")
    if integ not in INTEGRATORS and integ not in TREE_INTEGRATORS:
        every = INTEGRATORS + tuple(i for i in TREE_INTEGRATORS if i not in INTEGRATORS)
        raise ConfigError("integrator", integ, _suggest(str(integ), every), where=where)
    g = _num(sc, "g", where, G_DEFAULT, lo=0.0)
    gdir = (0.0, 0.0, -1.0)
    if "gravity" in sc:
        if "g" in sc:
            raise ConfigError("g", sc["g"], "left out where gravity is given (g is gravity's magnitude)", where=where)
        gv = _vec(sc, "gravity", 3, where)
        g = float(np.linalg.norm(gv))
        if g > 0 and not np.allclose(gv / g, gdir, rtol=0.0, atol=0.0):
            gdir = tuple(float(x) for x in gv / g)
    if _tree_syntax(data) or gdir != (0.0, 0.0, -1.0):
        return _tree_scene(data, sc, name, integ, g, where, source, gdir)
    bodies_tbl = data.get("body")
    if not isinstance(bodies_tbl, list) or not bodies_tbl:
        raise ConfigError("body", bodies_tbl, "at least one [[body]] table", where=source)
    bodies, terms = [], set()
    for i, b in enumerate(bodies_tbl):
        bs, t = _body(b, i, g, source)
        bodies.extend(bs)
        terms |= t
    names = [b.name for b in bodies]
    if len(set(names)) != len(names):
        dup = next(n for n in names if names.count(n) > 1)
        raise ConfigError("name", dup, "unique body names", where=source)
    return _one_body_scene(name, tuple(bodies), terms, integ, g, sc, where, source)


def _one_body_scene(name, bodies, terms, integ, g, sc, where, source) -> Scene:
    """A scene on the one-body kernel: independent bodies, each integrated by Euler's equations."""
    if integ not in INTEGRATORS:
        raise ConfigError("integrator", integ, f"one of {', '.join(INTEGRATORS)} for a scene of independent bodies "
                          f"('{integ}' integrates a tree of bodies: give a body a `joint` to run it on the tree "
                          "engine)", where=where)
    scene = Scene(
        name=name, bodies=tuple(bodies), gravity="gravity" in terms, damping="damping" in terms,
        torque="torque" in terms, integrator=integ,
        max_step=_num(sc, "max_step", where, 1e-3, lo=0.0, lo_open=True),
        max_drift=_num(sc, "max_drift", where, _engine.MAX_DRIFT, lo=0.0, lo_open=False),
        tolerance=_tolerance(sc, where),
        output_interval=_num(sc, "output_interval", where, 0.01, lo=0.0, lo_open=True),
        stop_time=_num(sc, "stop_time", where, 10.0, lo=0.0, lo_open=True),
        g=g, description=str(sc.get("description", "")), source=source)
    if integ == "exact" and scene.exact_start() is not None:
        raise ConfigError("integrator", integ, "a general integrator: 'exact' solves a torque-free body or a "
                          f"Lagrange top only, and this scene has {scene.exact_start()}", where=where)
    return scene


def _tree_syntax(data: dict) -> bool:
    """True where a scene uses the tree syntax (a joint, a parent, couplings, scene parameters, elements, contact,
    closed loops, gears or an orbit)."""
    from .scene_tree import TREE_KEYS

    bodies = data.get("body")
    sc = data.get("scene")
    return ("coupling" in data or "parameters" in data or "spring" in data or "force" in data or "shape" in data or
            "plane" in data or "loop" in data or "gear" in data or
            (isinstance(sc, dict) and "orbit" in sc) or
            (isinstance(bodies, list) and any(isinstance(b, dict) and any(k in b for k in TREE_KEYS) for b in bodies)))


#: The integrators of the tree engine (exact and the exact-flow splittings solve one body; midpoint and
#: energy_momentum, the implicit methods on the rotation group, solve trees; splitting and splitting4 solve a gyrostat
#: tree by its exact flows).
TREE_INTEGRATORS = ("euler", "rk4", "adaptive", "dop853", "midpoint", "energy_momentum", "splitting", "splitting4")


def _one_body_kernel(data: dict, bodies, couplings, aliases, orbit, g, source) -> tuple[BodySpec, set] | None:
    """The body and terms of the one-body kernel (Euler's equations in closed form, the exact flows, the
    splittings) where a tree is one body that kernel describes exactly, else None (docs/trees.md: the engine picks
    the kernels that fit a system).

    That is a root on a ``free_rotation`` or ``ball`` joint at the world's origin, with its inertia along its
    body axes and its centre of mass on body +z given as ``cm_distance`` (the one-body meaning: I1, I2, I3 about
    the pivot) or at the joint point; no couplings, scene parameters or orbit. The body is read by the one-body
    parser from the same table, so its numbers are the user's to the bit, and its variables mean what a one-body
    scene's do under the same bare names. Any other tree runs on the articulated-body algorithm."""
    if len(bodies) != 1 or couplings or aliases or orbit is not None:
        return None
    b, tbl = bodies[0], data["body"][0]
    if b.parent != -1 or b.joint not in ("free_rotation", "ball") or np.any(b.pos != 0.0):
        return None
    if not np.array_equal(b.rotation, [1.0, 0.0, 0.0, 0.0]) or np.any(b.ball_stiffness) or np.any(b.ball_damping):
        return None  # a placement, a ball spring or damping per axis: the tree engine's terms
    J = np.asarray(b.inertia, dtype=float)
    if np.any(J != np.diag(np.diag(J))) or b.cm[0] != 0.0 or b.cm[1] != 0.0:
        return None
    if b.cm[2] != 0.0 and ("cm" in tbl or b.joint != "ball"):  # `cm`: inertia about the centre of mass
        return None
    try:
        keys = {k: v for k, v in tbl.items() if k in _BODY_KEYS}
        if "joint_damping" in tbl:   # a ball's joint_damping is its damping (DESIGN 4b)
            keys["damping"] = tbl["joint_damping"]
        (body,), terms = _body(keys, 0, g, source)
    except ConfigError:  # a body the one-body kernel does not take (a flat body, a massless one)
        return None
    if not (np.array_equal(body.q0, b.q0) and np.array_equal(body.omega0, b.omega0)):
        return None  # its principal axes are not its body axes
    return body, terms


def _tree_scene(data, sc, name, integ, g, where, source, gdir=(0.0, 0.0, -1.0)) -> Scene:
    from .scene_contact import planes_from_dict, shapes_from_dict
    from .scene_loops import check_closed, gears_from_dict, loops_from_dict, with_start_rotations
    from .scene_tree import check_inert_joints, orbit_from_dict, tree_from_dict

    bodies, couplings, cnames, aliases, springs, forces = tree_from_dict(data, source)
    orbit = orbit_from_dict(sc["orbit"], bodies, f"{where}.orbit") if "orbit" in sc else None
    names = [b.name for b in bodies]
    for nm in cnames:
        if nm in names or nm in [e.name for e in springs + forces]:
            raise ConfigError("name", nm, "a coupling name no body, spring or force of the scene has", where=source)
    taken = list(cnames) + [e.name for e in springs + forces]
    shapes = shapes_from_dict(data, names, taken, source)
    planes = planes_from_dict(data, taken + [h.name for h in shapes] + names, source)
    if shapes and not planes or planes and not shapes:
        raise ConfigError("shape" if planes else "plane", "none", "[[shape]] and [[plane]] tables together (a "
                          "shape touches planes)", where=source)
    taken += [h.name for h in shapes] + [p.name for p in planes]
    loops = loops_from_dict(data, bodies, taken, source)
    gears = gears_from_dict(data, bodies, taken + [lp.name for lp in loops], source)
    check_inert_joints(bodies, source)   # after the format's checks: a joint that carries nothing, before any run
    # a tree-only integrator keeps a tree of one body on the tree engine; so do elements and a turned gravity
    plain = not springs and not forces and not shapes and not loops and not gears and gdir == (0.0, 0.0, -1.0)
    one = (_one_body_kernel(data, bodies, couplings, aliases, orbit, g, source) if integ in INTEGRATORS and plain
           else None)
    if one is not None:  # a tree of one body that Euler's equations describe: the one-body kernel
        body, terms = one
        return _one_body_scene(name, (body,), terms, integ, g, sc, where, source)
    if integ not in TREE_INTEGRATORS:
        raise ConfigError("integrator", integ, f"one of {', '.join(TREE_INTEGRATORS)}: a tree of bodies is "
                          f"integrated by the tree engine ('{integ}' solves one body)", where=where)
    for what, count in (("coupling", len(couplings)), ("spring", len(springs)), ("force", len(forces)),
                        ("shape", len(shapes)), ("plane", len(planes)), ("loop", len(loops)),
                        ("gear", len(gears))):
        if count > _engine.TREE_ELEM_MAX:
            raise ConfigError(what, f"{count} [[{what}]] tables", f"at most {_engine.TREE_ELEM_MAX} in a tree",
                              where=source)
    check_closed(bodies, loops, gears, len(shapes) * len(planes), source)
    loops = with_start_rotations(loops, bodies)
    if integ in ("midpoint", "energy_momentum"):
        from .scene_tree import implicit_fits, implicit_refusal

        if not implicit_fits(bodies, orbit, bool(shapes)):
            raise ConfigError("integrator", integ, implicit_refusal(bodies, orbit, bool(shapes)), where=where)
    scene = Scene(
        name=name, bodies=(), gravity=g > 0, damping=any(b.damping > 0 for b in bodies),
        torque=any(b.torque_input or b.motor_input for b in bodies) or bool(forces), integrator=integ,
        max_step=_num(sc, "max_step", where, 1e-3, lo=0.0, lo_open=True),
        max_drift=_num(sc, "max_drift", where, _engine.MAX_DRIFT, lo=0.0, lo_open=False),
        tolerance=_tolerance(sc, where),
        output_interval=_num(sc, "output_interval", where, 0.01, lo=0.0, lo_open=True),
        stop_time=_num(sc, "stop_time", where, 10.0, lo=0.0, lo_open=True),
        g=g, description=str(sc.get("description", "")), source=source, tree=bodies, couplings=couplings,
        coupling_names=cnames, aliases=aliases, orbit=orbit, springs=springs, forces=forces, gravity_dir=gdir,
        shapes=shapes, planes=planes, loops=loops, gears=gears)
    if integ in ("splitting", "splitting4"):
        from .scene_tree import split_fits, split_refusal

        if not split_fits(scene):
            raise ConfigError("integrator", integ, split_refusal(), where=where)
    return scene


def full_scene() -> Scene:
    """The full model: one body with every term (gravity, damping, torque inputs) and every variable."""
    return Scene(name="full", bodies=(BodySpec("body", np.array([1.0, 2.0, 3.0]), 1.0, 0.0, 0.0,
                                               np.array([1.0, 0.0, 0.0, 0.0]), np.array([1.0, 0.1, 0.1])),),
                 gravity=True, damping=True, torque=True, integrator="rk4", max_step=1e-3,
                 description="Full rigid-body model with every variable")


@functools.cache
def _embedded_scene(name: str) -> Scene:
    """An embedded scene, parsed once per process (scenes are frozen; Model copies their arrays)."""
    text = resources.files(__package__).joinpath("scenes", f"{name}.toml").read_text()
    return scene_from_dict(tomllib.loads(text), f"<embedded scene {name}>")


def read_scene_file(scene: str | Path) -> dict:
    """A scene file's TOML as a dict (the one reader of scene files: load_scene, the sweeps' [sweep] table).

    Raises
    ------
    ConfigError
        Not a file (:class:`SceneNotFoundError`, with the embedded names and a "did you mean"), not UTF-8 text (an
        FMU is named as one), unreadable, or invalid TOML.
    """
    s = str(scene)
    path = Path(s)
    if not path.is_file():
        names = EMBEDDED_SCENES + ("full",)
        what = "is a folder" if path.is_dir() else "not found"
        raise SceneNotFoundError(s, f"scene {s!r} {what}{did_you_mean(s, names, cutoff=0.5)}: give an embedded "
                                    f"scene ({', '.join(names)}) or the path of a TOML scene file")
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        what = ("an FMU (run it with `gyrosim simulate FILE.fmu` or FMPy)" if path.suffix.lower() == ".fmu"
                else "not a text file")
        raise ConfigError("scene", s, f"a TOML scene file (UTF-8 text); {path.name} is {what}") from None
    except OSError as e:
        raise SceneNotFoundError(s, f"scene file {s!r} cannot be read: {e.strerror or e}") from None
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise ConfigError("TOML", str(e), "a valid TOML document", where=str(path)) from None


def load_scene(scene: str | Path | Scene | None) -> Scene:
    """Load a scene by embedded name, TOML path, or pass a :class:`Scene` through; ``None`` = the full model.

    Raises
    ------
    ConfigError
        Unknown name or missing file (:class:`SceneNotFoundError`: "not found", with the embedded names and a
        "did you mean"), invalid TOML, or an invalid entry.
    """
    if scene is None:
        return full_scene()
    if isinstance(scene, Scene):
        return scene
    s = str(scene)
    if s in EMBEDDED_SCENES:
        return _embedded_scene(s)
    elif s == "full":
        return full_scene()
    else:
        data, source = read_scene_file(s), s
    return scene_from_dict(data, source)
