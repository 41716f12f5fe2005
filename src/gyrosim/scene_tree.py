"""Tree scenes: bodies joined by joints (docs/trees.md), parsed from the TOML structure.

A scene is a tree when a ``[[body]]`` has ``parent`` or ``joint``, or the scene has ``[[coupling]]`` or
``[parameters]``. Its format (every key optional unless said)::

    [[body]]
    name = "rotor"                   # required, unique
    parent = "inner"                 # a body above this one, or "world" (default)
    joint = "hinge"                  # free_rotation, ball, hinge, free, fixed (default: ball with cm_distance,
                                     # free_rotation otherwise)
    position = [0, 0, 0]             # m, the joint point in the parent's frame (the world for a root)
    axis = [0, 0, 1]                 # hinge: unit axis in the parent's frame (equal in the child at angle 0)
    mass = 0.5                       # kg
    cm = [0, 0, 0.05]                # m, centre of mass in the body frame from the joint point
    inertia = { principal = [..] }   # kg*m^2 about the centre of mass ({tensor = ..} or {shape = ..} as a body of
                                     # a one-body scene); with cm_distance and no cm: about the pivot, as today
    stiffness = 0.0                  # hinge spring, N*m/rad, about rest_angle (rad)
    joint_damping = 0.0              # hinge viscous damping, N*m*s/rad
    damping = 0.0                    # ball, free_rotation, free: viscous torque -damping*omega (N*m*s)
    motor_input = true               # hinge: an input motor_torque (N*m)
    torque_input = true              # inputs tau_x, tau_y, tau_z: an external torque in the body frame (N*m)
    angle = 0.0                      # hinge start angle (rad) and rate = 0.0 (rad/s)
    attitude = { zyz = [..] }        # ball, free_rotation, free: as a one-body scene; rates = { omega = [..] }
    r = [0, 0, 0]                    # free: start position (m, world) and v = [..] (m/s, world)

    [[coupling]]                     # a torsion spring between two hinges: -k (angle_a - angle_b) on a
    name = "coupling"                # the parameter's name (N*m/rad)
    bodies = ["left", "right"]
    stiffness = 1.0

    [scene.orbit]                    # the tree on an orbit about a central body (orbit_from_dict)
    mu = 3.986004418e14              # m^3/s^2, the central body's gravitational parameter (default: the Earth's)
    radius = 7.0e6                   # m: a circular orbit of the tree's reference point (x-y plane, normal +z);
    anomaly = 0.0                    # rad, its start anomaly. Without radius: every root is free, the world origin
                                     # is the central body's centre, and the roots move under the central force

    [parameters.L1]                  # a scene parameter that sets body parameters (each = factor * value)
    value = 1.0
    unit = "m"
    description = "length of the upper rod"
    sets = { "upper.cm_z" = -1.0, "lower.pos_z" = -1.0 }
    exclusive_min = 0.0              # its range: min / exclusive_min (x >= min / x > exclusive_min) and max /
                                     # exclusive_max, in its unit; narrowed by its targets' rules (a factor onto a
                                     # mass: >= 0). Checked at load and at every set (docs/scenes.md)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .core.inertia import InertiaTensor
from .core.tree import BODY_OUTPUTS, JOINT_COORDS, JOINTS, MU_EARTH, ORBIT_BODY_OUTPUTS, Orbit, TreeBody
from .errors import ConfigError
from .ranges import NONNEGATIVE, Range

__all__ = ["Alias", "tree_from_dict", "orbit_from_dict", "BODY_PARAMS", "BODY_VARIABLES", "TREE_KEYS",
           "NONNEGATIVE_PARAMS"]

_TREE_BODY_KEYS = ("name", "parent", "joint", "position", "axis", "mass", "cm", "cm_distance", "inertia",
                   "stiffness", "rest_angle", "joint_damping", "damping", "motor_input", "torque_input", "attitude",
                   "rates", "angle", "rate", "r", "v")

#: The keys of a [parameters.NAME] table: its range's bounds after the rest.
_RANGE_KEYS = ("min", "max", "exclusive_min", "exclusive_max")
_PARAMETER_KEYS = ("value", "unit", "description", "sets") + _RANGE_KEYS

#: Keys that make a scene a tree.
TREE_KEYS = ("parent", "joint")

#: The parameters every tree body has (docs/trees.md) and those of its joint, with unit and meaning.
BODY_PARAMS = {
    "mass": ("kg", "mass"),
    "I1": ("kg.m2", "moment of inertia about body x through the centre of mass"),
    "I2": ("kg.m2", "moment of inertia about body y through the centre of mass"),
    "I3": ("kg.m2", "moment of inertia about body z through the centre of mass"),
    "cm_x": ("m", "centre of mass from the joint point, body x"),
    "cm_y": ("m", "centre of mass from the joint point, body y"),
    "cm_z": ("m", "centre of mass from the joint point, body z"),
    "pos_x": ("m", "joint point in the parent's frame, x"),
    "pos_y": ("m", "joint point in the parent's frame, y"),
    "pos_z": ("m", "joint point in the parent's frame, z"),
}
HINGE_PARAMS = {
    "stiffness": ("N.m/rad", "hinge spring stiffness about rest_angle"),
    "rest_angle": ("rad", "hinge spring rest angle"),
    "joint_damping": ("N.m.s/rad", "hinge viscous damping"),
}
BALL_PARAMS = {"damping": ("N.m.s", "viscous torque -damping*omega (relative to the parent)")}
#: The body parameters that must be >= 0 (point masses and massless gimbals are allowed: a tree body may have 0).
NONNEGATIVE_PARAMS = ("mass", "I1", "I2", "I3", "stiffness", "joint_damping", "damping")
#: The short names of a body's own variables (a body's part of a name under Scene.var_name's rule).
BODY_VARIABLES = frozenset({*BODY_PARAMS, *HINGE_PARAMS, *BALL_PARAMS, "motor_torque", "tau_x", "tau_y", "tau_z",
                            *(c for cs in JOINT_COORDS.values() for c in cs), *BODY_OUTPUTS, *ORBIT_BODY_OUTPUTS})


@dataclass(frozen=True)
class Alias:
    """A scene parameter that sets body parameters: ``target = factor * value`` for each target.

    ``range`` is the values it may take: the scene file's ``min``/``max`` (``exclusive_min``/``exclusive_max``)
    narrowed by its targets' rules (a positive factor onto a mass: >= 0)."""

    name: str
    value: float
    unit: str
    description: str
    sets: tuple  # ((body index, parameter, factor), ...)
    range: Range = Range()


def _h():  # the helpers of scene.py (imported late: scene.py imports this module)
    from . import scene

    return scene


def _inertia_about_cm(spec, where, mass, cm_distance, cm_given):
    """(3, 3) inertia about the centre of mass in the body frame, and the shape's mass (or None)."""
    s = _h()
    if not isinstance(spec, dict):
        raise ConfigError("inertia", spec, "a table: {principal = [..]}, {tensor = [[..]]} or {shape = ..}",
                          where=where)
    w = f"{where}.inertia"
    if "shape" in spec:
        shape = spec["shape"]
        if not isinstance(shape, str) or shape not in s._SHAPES:
            raise ConfigError("shape", shape, s._suggest(str(shape), list(s._SHAPES)), where=w)
        s._check_keys(spec, ("shape",) + s._SHAPES[shape], w)
        args = [s._num(spec, k, w, required=True, lo=0.0, lo_open=(k in ("mass", "radius")))
                for k in s._SHAPES[shape]]
        return getattr(InertiaTensor, shape)(*args).to_matrix(), args[0]
    key = s._one_of(spec, ("principal", "tensor"), w)
    if key == "principal":
        m = s._vec(spec, "principal", 3, w)
        for n, v in zip(("I1", "I2", "I3"), m):
            if v < 0:
                raise ConfigError(f"principal ({n})", float(v), "a number >= 0 in kg*m^2", where=w)
        J = np.diag(m)
    else:
        T = spec["tensor"]
        if not isinstance(T, list) or len(T) != 3 or any(not isinstance(r, list) or len(r) != 3 for r in T):
            raise ConfigError("tensor", T, "a 3x3 list of lists in kg*m^2", where=w)
        try:
            J = InertiaTensor.from_matrix(np.array(T, dtype=float)).to_matrix()
        except (ConfigError, ValueError, TypeError) as e:
            raise ConfigError("tensor", T, getattr(e, "allowed", str(e)), where=w) from None
    if cm_distance and not cm_given:  # today's meaning: about the pivot, the centre of mass on +z
        J = J - mass * cm_distance ** 2 * np.diag([1.0, 1.0, 0.0])
        if np.any(np.diag(J) < -1e-12 * max(1.0, float(np.max(np.abs(J))))):
            raise ConfigError("inertia", spec, f"moments about the pivot of at least mass*cm_distance^2 = "
                              f"{mass * cm_distance ** 2:.6g} kg*m^2 about x and y", where=where)
        J[np.diag_indices(3)] = np.maximum(np.diag(J), 0.0)
    check_moments(np.diag(J), where)
    return J, None


def check_moments(m, where, names=("I1", "I2", "I3")):
    """Moments about the centre of mass: finite and >= 0 (point masses allowed). The triangle inequality is not
    asked of a tree body: a hub's listed inertia may leave out the parts modelled as bodies of their own (a
    spacecraft whose whole inertia is diag(1, 2, 3) kg*m^2 with its wheels)."""
    for n, v in zip(names, m):
        if not (math.isfinite(v) and v >= 0):
            raise ConfigError(n, float(v), "a finite number >= 0 in kg*m^2 (about the centre of mass)", where=where)


def _bool(tbl, key, where):
    v = tbl.get(key, False)
    if not isinstance(v, bool):
        raise ConfigError(key, v, "true or false", where=where)
    return v


def _tree_body(tbl, index, names, where):
    s = _h()
    where = f"{where} body[{index}]"
    if not isinstance(tbl, dict):
        raise ConfigError("body", tbl, "a table ([[body]])", where=where)
    s._check_keys(tbl, _TREE_BODY_KEYS, where)
    name = tbl.get("name", "body" if index == 0 else f"body_{index}")
    if not isinstance(name, str) or not name or not all(c.isalnum() or c in "_-" for c in name):
        raise ConfigError("name", name, "a non-empty name of letters, digits, '_' and '-' (it is a Zenoh key)",
                          where=where)
    where = f"{where} ({name!r})"
    parent = tbl.get("parent", "world")
    if parent == "world":
        pi = -1
    elif parent in names:
        pi = names.index(parent)
    else:
        raise ConfigError("parent", parent, f"'world' or a body defined above this one ({', '.join(names) or 'none'})"
                          f"{s.did_you_mean(parent, names + ['world'])}", where=where)
    joint = tbl.get("joint", "ball" if "cm_distance" in tbl else "free_rotation")
    if not isinstance(joint, str) or joint not in JOINTS:
        raise ConfigError("joint", joint, s._suggest(str(joint), list(JOINTS)), where=where)
    if joint == "free" and pi != -1:
        raise ConfigError("joint", joint, "'free' on a root only (parent = 'world')", where=where)
    only = {"axis": ("hinge",), "stiffness": ("hinge",), "rest_angle": ("hinge",), "joint_damping": ("hinge",),
            "motor_input": ("hinge",), "angle": ("hinge",), "rate": ("hinge",),
            "damping": ("ball", "free_rotation", "free"), "attitude": ("ball", "free_rotation", "free"),
            "rates": ("ball", "free_rotation", "free"), "r": ("free",), "v": ("free",)}
    for k, joints in only.items():
        if k in tbl and joint not in joints:
            hint = " (a hinge takes joint_damping)" if k == "damping" else ""
            raise ConfigError(k, tbl[k], f"a key of a {' or '.join(joints)} joint; this body's joint is "
                              f"{joint!r}{hint}", where=where)
    pos = s._vec(tbl, "position", 3, where) if "position" in tbl else np.zeros(3)
    axis = np.array([0.0, 0.0, 1.0])
    if "axis" in tbl:
        axis = s._vec(tbl, "axis", 3, where)
        n = float(np.linalg.norm(axis))
        if not n > 0:
            raise ConfigError("axis", tbl["axis"], "a non-zero vector (it is normalised)", where=where)
        axis = axis / n
    mass = s._num(tbl, "mass", where, None, lo=0.0)
    cm_d = s._num(tbl, "cm_distance", where, 0.0, lo=0.0)
    if "cm" in tbl and "cm_distance" in tbl:
        raise ConfigError("cm_distance", tbl["cm_distance"], "left out where cm is given (cm is the whole centre "
                          "of mass)", where=where)
    if "inertia" not in tbl:
        raise ConfigError("inertia", None, "a table (this key is required)", where=where)
    J, shape_mass = _inertia_about_cm(tbl["inertia"], where, mass or 0.0, cm_d, "cm" in tbl)
    if mass is None:
        mass = shape_mass if shape_mass is not None else 0.0
    elif shape_mass is not None and abs(shape_mass - mass) > 1e-12 * max(shape_mass, mass):
        raise ConfigError("mass", mass, f"the shape's mass {shape_mass} (or leave body.mass out)", where=where)
    cm = s._vec(tbl, "cm", 3, where) if "cm" in tbl else np.array([0.0, 0.0, cm_d])
    if cm_d and not mass > 0:
        raise ConfigError("mass", tbl.get("mass"), "a number > 0 for a body with cm_distance", where=where)
    kw = dict(name=name, parent=pi, joint=joint, pos=pos, axis=axis, mass=float(mass), cm=cm, inertia=J,
              stiffness=s._num(tbl, "stiffness", where, 0.0, lo=0.0),
              rest_angle=s._num(tbl, "rest_angle", where, 0.0),
              damping=s._num(tbl, "joint_damping" if joint == "hinge" else "damping", where, 0.0, lo=0.0),
              motor_input=_bool(tbl, "motor_input", where), torque_input=_bool(tbl, "torque_input", where),
              angle0=s._num(tbl, "angle", where, 0.0), rate0=s._num(tbl, "rate", where, 0.0))
    if "r" in tbl:
        kw["r0"] = s._vec(tbl, "r", 3, where)
    if "v" in tbl:
        kw["v0"] = s._vec(tbl, "v", 3, where)
    kw["q0"], kw["omega0"] = s._attitude_rates(tbl, where)
    return TreeBody(**kw)


_ALIAS_TARGETS = tuple(BODY_PARAMS) + tuple(HINGE_PARAMS) + tuple(BALL_PARAMS)


def body_with(b: TreeBody, param: str, x: float) -> TreeBody:
    """``b`` with one of its parameters (BODY_PARAMS, HINGE_PARAMS, BALL_PARAMS) set to ``x``."""
    if param == "mass":
        return replace(b, mass=x)
    if param in ("I1", "I2", "I3"):
        J = np.array(b.inertia, dtype=float)
        k = int(param[1]) - 1
        J[k, k] = x
        return replace(b, inertia=J)
    if param.startswith("cm_") or param.startswith("pos_"):
        head, tail = param.split("_")
        v = np.array(getattr(b, head), dtype=float)
        v["xyz".index(tail)] = x
        return replace(b, **{head: v})
    if param in ("joint_damping", "damping"):
        return replace(b, damping=x)
    return replace(b, **{param: x})


def tree_from_dict(data: dict, source: str):
    """The tree's bodies, couplings and aliases from a parsed scene: ``(bodies, couplings, coupling names,
    aliases)``; raises :class:`ConfigError` naming the key, the value and what is allowed."""
    s = _h()
    bodies_tbl = data.get("body")
    if not isinstance(bodies_tbl, list) or not bodies_tbl:
        raise ConfigError("body", bodies_tbl, "at least one [[body]] table", where=source)
    bodies, names = [], []
    for i, tbl in enumerate(bodies_tbl):
        if isinstance(tbl, dict) and "count" in tbl:
            raise ConfigError("count", tbl["count"], "left out of a tree scene (a body of a tree is one body)",
                              where=f"{source} body[{i}]")
        b = _tree_body(tbl, i, names, source)
        if b.name in names:
            raise ConfigError("name", b.name, "unique body names", where=source)
        bodies.append(b)
        names.append(b.name)
    from .core import _engine

    if len(bodies) > _engine.TREE_MAX:
        raise ConfigError("body", f"{len(bodies)} bodies", f"at most {_engine.TREE_MAX} bodies in a tree",
                          where=source)
    couplings, cnames = [], []
    cl = data.get("coupling", [])
    if not isinstance(cl, list):
        raise ConfigError("coupling", cl, "[[coupling]] tables", where=source)
    for i, c in enumerate(cl):
        w = f"{source} coupling[{i}]"
        if not isinstance(c, dict):
            raise ConfigError("coupling", c, "a table ([[coupling]])", where=w)
        s._check_keys(c, ("name", "bodies", "stiffness"), w)
        nm = c.get("name", "coupling" if i == 0 else f"coupling_{i}")
        if not isinstance(nm, str) or not nm.isidentifier() or nm in cnames:
            raise ConfigError("name", nm, "a unique identifier (the parameter's name)", where=w)
        pair = c.get("bodies")
        if not (isinstance(pair, list) and len(pair) == 2 and all(p in names for p in pair) and pair[0] != pair[1]):
            raise ConfigError("bodies", pair, f"two different bodies of the scene ({', '.join(names)})", where=w)
        ia, ib = names.index(pair[0]), names.index(pair[1])
        for nm_b, ix in zip(pair, (ia, ib)):
            if bodies[ix].joint != "hinge":
                raise ConfigError("bodies", pair, f"two hinge bodies; {nm_b!r} has joint {bodies[ix].joint!r}",
                                  where=w)
        couplings.append((ia, ib, s._num(c, "stiffness", w, 0.0, lo=0.0)))
        cnames.append(nm)
    aliases = []
    pt = data.get("parameters", {})
    if not isinstance(pt, dict):
        raise ConfigError("parameters", pt, "a table of [parameters.NAME] tables", where=source)
    for an, spec in pt.items():
        w = f"{source} [parameters.{an}]"
        if not isinstance(spec, dict):
            raise ConfigError(an, spec, "a table with value, unit, description and sets", where=w)
        s._check_keys(spec, _PARAMETER_KEYS, w)
        value = s._num(spec, "value", w, required=True)
        unit = str(spec.get("unit", ""))
        declared = _declared_range(spec, w, unit)
        sets = spec.get("sets")
        if not isinstance(sets, dict) or not sets:
            raise ConfigError("sets", sets, "a table {\"<body>.<parameter>\" = factor, ...}", where=w)
        targets = []
        for tgt, f in sets.items():
            bn, _, pn = str(tgt).partition(".")
            if bn not in names or pn not in _ALIAS_TARGETS:
                raise ConfigError("sets", tgt, f"<body>.<parameter> with a body of the scene and a parameter of "
                                  f"{', '.join(_ALIAS_TARGETS)}", where=w)
            if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f):
                raise ConfigError(str(tgt), f, "a finite factor", where=w)
            targets.append((names.index(bn), pn, float(f)))
        rng = declared
        for _, pn, f in targets:  # a target that must be >= 0: the parameter on the side its factor allows
            if pn in NONNEGATIVE_PARAMS and f != 0.0:
                rng = rng.intersect(NONNEGATIVE if f > 0 else Range(max=0.0))
        if rng.empty:
            rules = ", ".join(f"{names[bi]}.{pn} >= 0" for bi, pn, _ in targets if pn in NONNEGATIVE_PARAMS)
            raise ConfigError("sets", sets, f"targets that a value {declared.text(unit)} keeps within their rules "
                              f"({rules})", where=w)
        if value not in declared:
            raise ConfigError("value", value, f"{declared.text(unit)} (the range its min/max give)", where=w)
        if value not in rng:
            bad = next(f"{names[bi]}.{pn} = {f!r} * value" for bi, pn, f in targets
                       if pn in NONNEGATIVE_PARAMS and not f * value >= 0)
            raise ConfigError("value", value, f"{rng.text(unit)}: it sets {bad}, which must be >= 0", where=w)
        aliases.append(Alias(an, value, unit, str(spec.get("description", "")), tuple(targets), rng))
        for bi, pn, f in targets:
            bodies[bi] = body_with(bodies[bi], pn, f * value)
    return tuple(bodies), tuple(couplings), tuple(cnames), tuple(aliases)


def _declared_range(spec: dict, where: str, unit: str) -> Range:
    """The range a ``[parameters.X]`` table gives: ``min`` (x >= min) or ``exclusive_min`` (x > it), ``max`` or
    ``exclusive_max``; finite numbers in the parameter's unit, one lower and one upper bound at most, a range that
    holds a number."""
    s = _h()
    b = {k: s._num(spec, k, where) for k in _RANGE_KEYS if k in spec}
    for side in ("min", "max"):
        if side in b and f"exclusive_{side}" in b:
            raise ConfigError(f"exclusive_{side}", b[f"exclusive_{side}"], f"left out where {side} is given (one "
                              f"{'lower' if side == 'min' else 'upper'} bound: {side} = x for "
                              f"{'>=' if side == 'min' else '<='} x, exclusive_{side} = x for "
                              f"{'>' if side == 'min' else '<'} x)", where=where)
    lo_key = "exclusive_min" if "exclusive_min" in b else "min"
    hi_key = "exclusive_max" if "exclusive_max" in b else "max"
    r = Range(b.get(lo_key, -math.inf), b.get(hi_key, math.inf), lo_key in b and lo_key != "min",
              hi_key in b and hi_key != "max")
    if r.empty:
        raise ConfigError(hi_key, b[hi_key], f"an upper bound above the lower one ({lo_key} = {b[lo_key]!r} "
                          f"{unit or '1'})", where=where)
    return r


def orbit_from_dict(tbl, bodies, where: str) -> Orbit:
    """The ``[scene.orbit]`` table of a tree scene: ``mu`` (m^3/s^2 > 0, default the Earth's), ``radius`` (m > 0: a
    circular orbit) and ``anomaly`` (rad, its start), or no radius: every root ``free`` with ``r`` away from the
    central body (the world origin)."""
    s = _h()
    if not isinstance(tbl, dict):
        raise ConfigError("orbit", tbl, "a table [scene.orbit] with mu, radius, anomaly", where=where)
    s._check_keys(tbl, ("mu", "radius", "anomaly"), where)
    mu = s._num(tbl, "mu", where, MU_EARTH, lo=0.0, lo_open=True)
    radius = s._num(tbl, "radius", where, None, lo=0.0, lo_open=True)
    if radius is None:
        if "anomaly" in tbl:
            raise ConfigError("anomaly", tbl["anomaly"], "left out without radius (the anomaly of a circular orbit; "
                              "a Kepler orbit starts from the free roots' r and v)", where=where)
        for b in bodies:
            if b.parent < 0 and b.joint != "free":
                raise ConfigError("radius", None, f"a number > 0 in m (a circular orbit), or every root joint "
                                  f"'free' (a Kepler orbit from its r, v); root {b.name!r} has joint {b.joint!r}",
                                  where=where)
            if b.parent < 0 and not float(np.linalg.norm(b.r0)) > 0:
                raise ConfigError("r", b.r0.tolist(), "a position away from the central body (the world origin) on "
                                  f"a Kepler orbit (root {b.name!r}, m)", where=where)
        return Orbit(mu=mu)
    return Orbit(mu=mu, radius=radius, anomaly=s._num(tbl, "anomaly", where, 0.0))
