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
from .ranges import BOUNDED, NONNEGATIVE, Range

__all__ = ["Alias", "tree_from_dict", "orbit_from_dict", "BODY_PARAMS", "BODY_VARIABLES", "TREE_KEYS",
           "NONNEGATIVE_PARAMS"]

_TREE_BODY_KEYS = ("name", "parent", "joint", "position", "axis", "mass", "cm", "cm_distance", "inertia",
                   "stiffness", "rest_angle", "joint_damping", "damping", "motor_input", "torque_input", "attitude",
                   "rates", "angle", "rate", "r", "v", "rotation", "displacement", "velocity", "rest_displacement",
                   "lower", "upper", "stop", "restitution", "stop_stiffness", "stop_damping", "motor_torque",
                   "motor_force")
_SPRING_KEYS = ("name", "body_a", "point_a", "body_b", "point_b", "stiffness", "rest_length", "damping")
_FORCE_KEYS = ("name", "body", "point", "frame")
#: The stops' default spring-damper: a critically damped contact of time constant STOP_TIME (s) for the joint's
#: inertia M (its subtree's moment about the axis, or its mass for a slider, at the joint's zero): k = M / tau^2,
#: c = 2 M / tau.
STOP_TIME = 0.01

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
SLIDER_PARAMS = {
    "stiffness": ("N/m", "slider spring stiffness about rest_displacement"),
    "rest_displacement": ("m", "slider spring rest displacement"),
    "joint_damping": ("N.s/m", "slider viscous damping"),
}
BALL_PARAMS = {"damping": ("N.m.s", "viscous torque -damping*omega (relative to the parent)")}
#: A ball's spring (where the scene gives one) and its damping per axis (where given per axis).
BALL_SPRING_PARAMS = {f"stiffness_{c}": ("N.m/rad", f"ball spring stiffness about body {c} (the potential "
                                         "1/2 phi^T K phi, phi the rotation vector from the joint's zero)")
                      for c in "xyz"}
BALL_DAMPING_PARAMS = {f"joint_damping_{c}": ("N.m.s/rad", f"ball viscous damping about body {c}") for c in "xyz"}
#: A hinge's or slider's stops (where the scene gives them); units (rad or m) set per joint.
STOP_PARAMS = ("lower", "upper", "stop_stiffness", "stop_damping", "restitution")
#: The body parameters that must be >= 0 (point masses and massless gimbals are allowed: a tree body may have 0).
NONNEGATIVE_PARAMS = ("mass", "I1", "I2", "I3", "stiffness", "joint_damping", "damping", "stiffness_x", "stiffness_y",
                      "stiffness_z", "joint_damping_x", "joint_damping_y", "joint_damping_z", "stop_stiffness",
                      "stop_damping")
#: The short names of a body's own variables (a body's part of a name under Scene.var_name's rule).
BODY_VARIABLES = frozenset({*BODY_PARAMS, *HINGE_PARAMS, *SLIDER_PARAMS, *BALL_PARAMS, *BALL_SPRING_PARAMS,
                            *BALL_DAMPING_PARAMS, *STOP_PARAMS, "motor_torque", "motor_force", "tau_x", "tau_y",
                            "tau_z",
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
    name = s.check_name(tbl.get("name", "body" if index == 0 else f"body_{index}"), where, "body")
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
    balls = ("ball", "free_rotation", "free")
    only = {"axis": ("hinge", "slider"), "stiffness": ("hinge", "slider", "ball", "free_rotation"),
            "rest_angle": ("hinge",), "joint_damping": ("hinge", "slider", "ball", "free_rotation"),
            "motor_input": ("hinge", "slider"), "angle": ("hinge",), "rate": ("hinge",),
            "motor_torque": ("hinge",), "motor_force": ("slider",),
            "displacement": ("slider",), "velocity": ("slider",), "rest_displacement": ("slider",),
            "lower": ("hinge", "slider"), "upper": ("hinge", "slider"), "stop": ("hinge", "slider"),
            "restitution": ("hinge", "slider"), "stop_stiffness": ("hinge", "slider"),
            "stop_damping": ("hinge", "slider"),
            "damping": balls, "attitude": balls, "rates": balls, "r": ("free",), "v": ("free",),
            "rotation": ("ball", "free_rotation", "hinge", "slider", "fixed")}
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
    one = joint in ("hinge", "slider")
    kw = dict(name=name, parent=pi, joint=joint, pos=pos, axis=axis, mass=float(mass), cm=cm, inertia=J,
              stiffness=s._num(tbl, "stiffness", where, 0.0, lo=0.0) if one else 0.0,
              rest_angle=s._num(tbl, "rest_displacement" if joint == "slider" else "rest_angle", where, 0.0),
              damping=s._num(tbl, "joint_damping", where, 0.0, lo=0.0) if one else 0.0,
              motor_input=_bool(tbl, "motor_input", where), torque_input=_bool(tbl, "torque_input", where),
              angle0=s._num(tbl, "displacement" if joint == "slider" else "angle", where, 0.0),
              rate0=s._num(tbl, "velocity" if joint == "slider" else "rate", where, 0.0))
    motor_key = "motor_force" if joint == "slider" else "motor_torque"
    if motor_key in tbl:   # the motor input's start value: a constant drive unless something sets the input
        if not kw["motor_input"]:
            raise ConfigError(motor_key, tbl[motor_key], f"a start value of the input {motor_key}: only with "
                              "motor_input = true", where=where)
        v = s._num(tbl, motor_key, where, 0.0)
        if v not in BOUNDED:   # the input's range, as every door checks it
            raise ConfigError(motor_key, v, BOUNDED.text("N" if joint == "slider" else "N.m"), where=where)
        kw["motor0"] = v
    if joint in ("ball", "free_rotation", "free"):
        kw.update(_ball_spring_damping(tbl, joint, where))
    if "rotation" in tbl:
        kw["rotation"] = _rotation(tbl["rotation"], where)
    if one:
        kw.update(_stops(tbl, joint, where))
    if "r" in tbl:
        kw["r0"] = s._vec(tbl, "r", 3, where)
    if "v" in tbl:
        kw["v0"] = s._vec(tbl, "v", 3, where)
    kw["q0"], kw["omega0"] = s._attitude_rates(tbl, where)
    return TreeBody(**kw)


def _vec_or_scalar(tbl, key, where, unit):
    """A key given as one number (every axis) or 3 (per body axis), each >= 0: ``(values (3,), per_axis)``."""
    s = _h()
    v = tbl[key]
    if isinstance(v, list):
        x = s._vec(tbl, key, 3, where)
        per_axis = True
    else:
        x = np.full(3, s._num(tbl, key, where, 0.0))
        per_axis = False
    if not (np.all(np.isfinite(x)) and np.all(x >= 0)):
        raise ConfigError(key, v, f"a number >= 0 or 3 of them (per body axis) in {unit}", where=where)
    return x, per_axis


def _ball_spring_damping(tbl, joint, where) -> dict:
    """A ball's spring (``stiffness``: one number or 3, N*m/rad) and damping (``joint_damping`` or ``damping``: one
    number, the isotropic ``damping``, or 3 per body axis)."""
    out = {}
    if "stiffness" in tbl:
        if joint == "free":
            raise ConfigError("stiffness", tbl["stiffness"], "left out of a free joint (a ball's spring pulls "
                              "towards the joint's zero; a free root has none)", where=where)
        out["ball_stiffness"], _ = _vec_or_scalar(tbl, "stiffness", where, "N*m/rad")
    if "joint_damping" in tbl and "damping" in tbl:
        raise ConfigError("joint_damping", tbl["joint_damping"], "left out where damping is given (the two keys "
                          "mean the same on a ball joint)", where=where)
    key = "joint_damping" if "joint_damping" in tbl else "damping"
    if key in tbl:
        x, per_axis = _vec_or_scalar(tbl, key, where, "N*m*s/rad")
        if per_axis and joint == "free":
            raise ConfigError(key, tbl[key], "one number (N*m*s) on a free joint: the torque -damping*omega",
                              where=where)
        if per_axis:
            out["ball_damping"] = x
        else:
            out["damping"] = float(x[0])
    return out


def _rotation(spec, where) -> np.ndarray:
    """A joint's placement: ``{quaternion = [w, x, y, z]}`` (normalised) or ``{zyz = [phi, theta, psi]}`` (rad)."""
    s = _h()
    from .core.rotations import euler_zyz_to_quat

    if not isinstance(spec, dict):
        raise ConfigError("rotation", spec, "a table {quaternion = [w, x, y, z]} or {zyz = [phi, theta, psi]}",
                          where=where)
    w = f"{where}.rotation"
    k = s._one_of(spec, ("quaternion", "zyz"), w)
    v = s._vec(spec, k, 4 if k == "quaternion" else 3, w)
    if k == "zyz":
        return np.asarray(euler_zyz_to_quat(*v), dtype=float)
    n = float(np.linalg.norm(v))
    if not n > 0:
        raise ConfigError("quaternion", spec[k], "a non-zero quaternion [w, x, y, z] (it is normalised)", where=w)
    q = v / n
    return q if q[0] >= 0 else -q


def _stops(tbl, joint, where) -> dict:
    """A hinge's or slider's stops: ``lower`` and/or ``upper`` (rad, m; lower < upper) with ``stop = "spring"``
    and its ``stop_stiffness``, ``stop_damping`` (default: STOP_TIME's contact, set by the tree)."""
    s = _h()
    out = {}
    unit = "m" if joint == "slider" else "rad"
    for k in ("lower", "upper"):
        if k in tbl:
            out[k] = s._num(tbl, k, where, None)
    for k in ("stop", "restitution", "stop_stiffness", "stop_damping"):
        if k in tbl and not out:
            raise ConfigError(k, tbl[k], f"left out without lower or upper (the stops it sets, {unit})", where=where)
    if "lower" in out and "upper" in out and not out["lower"] < out["upper"]:
        raise ConfigError("upper", out["upper"], f"a number above lower = {out['lower']!r} {unit}", where=where)
    stop = tbl.get("stop", "spring")
    if stop not in ("spring", "impact"):
        raise ConfigError("stop", stop, "'spring' (a stiff spring-damper) or 'impact'", where=where)
    if stop == "impact":
        for k in ("stop_stiffness", "stop_damping"):
            if k in tbl:
                raise ConfigError(k, tbl[k], "left out of an impact stop (its law is the restitution's)", where=where)
        out["stop"] = "impact"
        out["restitution"] = s._num(tbl, "restitution", where, 1.0, lo=0.0)
        if out["restitution"] > 1.0:
            raise ConfigError("restitution", out["restitution"], "a number in [0, 1] (the rate after an impact over "
                              "the rate before)", where=where)
        key = "displacement" if joint == "slider" else "angle"   # an impact stop holds the joint within them
        x0 = s._num(tbl, key, where, 0.0)
        if not out.get("lower", -math.inf) <= x0 <= out.get("upper", math.inf):
            raise ConfigError(key, x0, f"a start within the impact stops [{out.get('lower', -math.inf)}, "
                              f"{out.get('upper', math.inf)}] {unit}", where=where)
        return out
    if "restitution" in tbl:
        raise ConfigError("restitution", tbl["restitution"], 'left out of a spring stop (or stop = "impact")',
                          where=where)
    for k in ("stop_stiffness", "stop_damping"):
        if k in tbl:
            out[k] = s._num(tbl, k, where, None, lo=0.0)
    return out


def stop_defaults(bodies: list) -> list:
    """The bodies with their stops' default spring-damper (STOP_TIME's critically damped contact) where the scene
    gave none: M the joint's inertia with its subtree at the joint's zero (a hinge: the subtree's moment about the
    axis through the joint point; a slider: the subtree's mass)."""
    out = list(bodies)
    for i, b in enumerate(bodies):
        if (b.lower is None and b.upper is None) or b.stop == "impact":
            continue
        M = _joint_inertia(bodies, i)
        k, c = M / STOP_TIME ** 2, 2.0 * M / STOP_TIME
        out[i] = replace(b, stop_stiffness=k if b.stop_stiffness is None else b.stop_stiffness,
                         stop_damping=c if b.stop_damping is None else b.stop_damping)
    return out


def _joint_inertia(bodies, i) -> float:
    """Body i's joint inertia with its subtree at every joint's zero (placements included): the moment about the
    hinge axis through the joint point, or the mass moved by a slider."""
    from .core.rotations import quat_to_matrix

    frames = {i: (np.eye(3), np.zeros(3))}   # body -> (R to body i's frame, its origin there)
    M = 0.0
    a = np.asarray(bodies[i].axis, dtype=float)
    R0 = quat_to_matrix(bodies[i].rotation)
    a = R0.T @ a   # the axis in body i's frame
    for j in range(i, len(bodies)):
        b = bodies[j]
        if j != i:
            if b.parent not in frames:
                continue
            Rp, op = frames[b.parent]
            frames[j] = (Rp @ quat_to_matrix(b.rotation), op + Rp @ np.asarray(b.pos, dtype=float))
        R, o = frames[j]
        if bodies[i].joint == "slider":
            M += b.mass
            continue
        c = o + R @ np.asarray(b.cm, dtype=float)
        Jc = R @ np.asarray(b.inertia, dtype=float) @ R.T
        M += float(a @ Jc @ a) + b.mass * float(c @ c - (a @ c) ** 2)
    return M


def springs_from_dict(data: dict, names: list, source: str) -> tuple:
    """The ``[[spring]]`` elements: between a point of ``body_a`` and one of ``body_b`` (``world`` allowed, not
    both), ``stiffness`` N/m, ``rest_length`` m, ``damping`` N*s/m, all >= 0."""
    from .core.tree import Spring

    s = _h()
    out = []
    for t, w, nm in _element_tables(data, "spring", _SPRING_KEYS, names, [], source):
        ends = []
        for side in ("a", "b"):
            bn = t.get(f"body_{side}", "world")
            if bn != "world" and bn not in names:
                raise ConfigError(f"body_{side}", bn, f"'world' or a body of the scene ({', '.join(names)})"
                                  f"{s.did_you_mean(str(bn), names + ['world'])}", where=w)
            pt = s._vec(t, f"point_{side}", 3, w) if f"point_{side}" in t else np.zeros(3)
            ends.append((-1 if bn == "world" else names.index(bn), pt))
        if ends[0][0] == ends[1][0]:
            raise ConfigError("body_b", t.get("body_b", "world"), "a body other than body_a (a spring joins two "
                              "bodies, or a body and the world)", where=w)
        out.append(Spring(nm, ends[0][0], ends[0][1], ends[1][0], ends[1][1],
                          stiffness=s._num(t, "stiffness", w, 0.0, lo=0.0),
                          rest_length=s._num(t, "rest_length", w, 0.0, lo=0.0),
                          damping=s._num(t, "damping", w, 0.0, lo=0.0)))
    return tuple(out)


def forces_from_dict(data: dict, names: list, taken: list, source: str) -> tuple:
    """The ``[[force]]`` inputs: a force (N) at ``point`` (m, body frame) of ``body``, in the body's ``frame`` or
    the ``world``'s; inputs ``<body>.<name>.f_x..z``."""
    from .core.tree import Force

    s = _h()
    out = []
    for t, w, nm in _element_tables(data, "force", _FORCE_KEYS, names, taken, source):
        bn = t.get("body")
        if bn not in names:
            raise ConfigError("body", bn, f"a body of the scene ({', '.join(names)})"
                              f"{s.did_you_mean(str(bn), names)}", where=w)
        frame = t.get("frame", "body")
        if frame not in ("body", "world"):
            raise ConfigError("frame", frame, "'body' (the force turns with the body: a thruster) or 'world'",
                              where=w)
        pt = s._vec(t, "point", 3, w) if "point" in t else np.zeros(3)
        out.append(Force(nm, names.index(bn), pt, frame == "world"))
    return tuple(out)


def _element_tables(data: dict, kind: str, keys: tuple, bodies: list, taken: list, source: str,
                    others: str = "body, spring or force"):
    """The ``[[kind]]`` tables of an element kind, checked as tables with known keys and a name (default ``kind``,
    ``kind_1``, ...) no body, earlier element (``taken``) or earlier table of this kind has: ``(table, where,
    name)`` each. ``others``: the named things a clash is checked against, as the message lists them."""
    s = _h()
    tl = data.get(kind, [])
    if not isinstance(tl, list):
        raise ConfigError(kind, tl, f"[[{kind}]] tables", where=source)
    seen = list(taken)
    for i, t in enumerate(tl):
        w = f"{source} {kind}[{i}]"
        if not isinstance(t, dict):
            raise ConfigError(kind, t, f"a table ([[{kind}]])", where=w)
        s._check_keys(t, keys, w)
        nm = t.get("name", kind if i == 0 else f"{kind}_{i}")
        if not isinstance(nm, str) or not nm or not all(c.isalnum() or c in "_-" for c in nm):
            raise ConfigError("name", nm, "a non-empty name of letters, digits, '_' and '-' (it names variables)",
                              where=w)
        if nm in bodies or nm in seen:
            raise ConfigError("name", nm, f"a name no {others} of the scene has", where=w)
        seen.append(nm)
        yield t, w, nm


def body_parameters(b: TreeBody) -> dict:
    """The parameters body ``b`` has, by short name -> (unit, description): every body's, its joint's, a ball's
    spring and per-axis damping where the scene gives them, its stops' where it has stops. The one list the
    variables (kernel_tree.tree_variables) and the scene parameters' targets are checked against."""
    params = dict(BODY_PARAMS)
    if b.joint == "hinge":
        params.update(HINGE_PARAMS)
    elif b.joint == "slider":
        params.update(SLIDER_PARAMS)
    elif b.joint in ("ball", "free_rotation", "free"):
        params.update(BALL_PARAMS)
        if np.any(b.ball_stiffness):
            params.update(BALL_SPRING_PARAMS)
        if np.any(b.ball_damping):
            params.update(BALL_DAMPING_PARAMS)
    unit = "m" if b.joint == "slider" else "rad"
    stiff = "N/m" if b.joint == "slider" else "N.m/rad"
    if b.lower is not None:
        params["lower"] = (unit, "lower stop")
    if b.upper is not None:
        params["upper"] = (unit, "upper stop")
    if (b.lower is not None or b.upper is not None) and b.stop == "impact":
        params["restitution"] = ("1", "coefficient of restitution of the impact stops (rate after / rate before)")
    elif b.lower is not None or b.upper is not None:
        params["stop_stiffness"] = (stiff, "stiffness of the stops' spring-damper")
        params["stop_damping"] = (stiff.replace("/", ".s/"), "damping of the stops' spring-damper (in contact)")
    return params


#: The parameter names a scene parameter may set (each checked against its target body's own: body_parameters).
_ALIAS_TARGETS = tuple(dict.fromkeys((*BODY_PARAMS, *HINGE_PARAMS, *SLIDER_PARAMS, *BALL_PARAMS, *BALL_SPRING_PARAMS,
                                      *BALL_DAMPING_PARAMS, *STOP_PARAMS)))   # once each (hinge and slider share)


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
    if param == "rest_displacement":
        return replace(b, rest_angle=x)
    if param.startswith(("stiffness_", "joint_damping_")):
        field_ = "ball_stiffness" if param.startswith("stiffness_") else "ball_damping"
        v = np.array(getattr(b, field_), dtype=float)
        v["xyz".index(param[-1])] = x
        return replace(b, **{field_: v})
    return replace(b, **{param: x})


#: The spring parameters a scene parameter may set (``"<spring>.stiffness" = factor``): the target's parameter is
#: named ``spring.<parameter>`` in Alias.sets, with the spring's index.
_SPRING_TARGETS = ("stiffness", "rest_length", "damping")


def tree_from_dict(data: dict, source: str):
    """The tree's bodies, couplings, aliases and elements from a parsed scene: ``(bodies, couplings, coupling names,
    aliases, springs, forces)``; raises :class:`ConfigError` naming the key, the value and what is allowed."""
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
        raise ConfigError("body", f"{len(bodies)} bodies", f"at most {_engine.TREE_MAX} bodies in a tree (the "
                          "engine's tree description holds that many)", where=source)
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
    springs = list(springs_from_dict(data, names, source))
    forces = forces_from_dict(data, names, [x.name for x in springs], source)
    snames = [x.name for x in springs]
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
            if bn in snames and pn in _SPRING_TARGETS:
                target = (snames.index(bn), f"spring.{pn}")
            elif bn not in names or pn not in _ALIAS_TARGETS:
                raise ConfigError("sets", tgt, f"<body>.<parameter> with a body of the scene and a parameter of "
                                  f"{', '.join(_ALIAS_TARGETS)}, or <spring>.<parameter> with a parameter of "
                                  f"{', '.join(_SPRING_TARGETS)}", where=w)
            elif pn not in body_parameters(bodies[names.index(bn)]):
                raise ConfigError("sets", tgt, f"a parameter body {bn!r} has: "
                                  f"{', '.join(body_parameters(bodies[names.index(bn)]))}", where=w)
            else:
                target = (names.index(bn), pn)
            if isinstance(f, bool) or not isinstance(f, (int, float)) or not math.isfinite(f):
                raise ConfigError(str(tgt), f, "a finite factor", where=w)
            targets.append((*target, float(f)))
        rng = declared

        def nonneg(pn):   # every spring parameter is >= 0
            return pn in NONNEGATIVE_PARAMS or pn.startswith("spring.")

        def label(i, pn):
            return f"{snames[i]}.{pn[7:]}" if pn.startswith("spring.") else f"{names[i]}.{pn}"

        for _, pn, f in targets:  # a target that must be >= 0: the parameter on the side its factor allows
            if nonneg(pn) and f != 0.0:
                rng = rng.intersect(NONNEGATIVE if f > 0 else Range(max=0.0))
        if rng.empty:
            rules = ", ".join(f"{label(bi, pn)} >= 0" for bi, pn, _ in targets if nonneg(pn))
            raise ConfigError("sets", sets, f"targets that a value {declared.text(unit)} keeps within their rules "
                              f"({rules})", where=w)
        if value not in declared:
            raise ConfigError("value", value, f"{declared.text(unit)} (the range its min/max give)", where=w)
        if value not in rng:
            bad = next(f"{label(bi, pn)} = {f!r} * value" for bi, pn, f in targets
                       if nonneg(pn) and not f * value >= 0)
            raise ConfigError("value", value, f"{rng.text(unit)}: it sets {bad}, which must be >= 0", where=w)
        aliases.append(Alias(an, value, unit, str(spec.get("description", "")), tuple(targets), rng))
        for bi, pn, f in targets:
            if pn.startswith("spring."):
                springs[bi] = replace(springs[bi], **{pn[7:]: f * value})
            else:
                bodies[bi] = body_with(bodies[bi], pn, f * value)
    return tuple(stop_defaults(bodies)), tuple(couplings), tuple(cnames), tuple(aliases), tuple(springs), forces


def check_inert_joints(bodies, source: str) -> None:
    """Refuse a tree with a joint that carries nothing whatever the configuration (:func:`inert_joints`): its
    equations of motion are singular everywhere, so no run can start."""
    for i, name, value, what, advice in inert_joints(bodies):
        raise ConfigError(name, value, f"a body with inertia at its joint: {what}, so nothing resists its joint's "
                          f"acceleration and the equations of motion are singular; {advice}",
                          where=f"{source} body[{i}] ({bodies[i].name!r})")


def inert_joints(bodies) -> list:
    """The joints that carry nothing whatever the configuration (the equations of motion singular everywhere), from
    the bodies' values: a body with neither mass nor inertia and nothing below it that has any (any joint with a
    coordinate; a fixed joint has none, so a massless fixed body, a sensor's frame, is fine), a hinge body whose mass
    sits on its axis with no moment about it and nothing below with any inertia, and a slider (or a free joint)
    whose subtree has no mass to move. As :meth:`gyrosim.kernel_tree.TreeKernel.inert_bodies` says it at run time.

    Returns
    -------
    list of (body index, parameter, value, what it is, advice)
        The parameter to name (``mass``; ``cm_x`` for a mass on a hinge's axis) and its value.
    """
    below = {i: [] for i in range(len(bodies))}
    for i, b in enumerate(bodies):
        j = b.parent
        while j >= 0:
            below[j].append(i)
            j = bodies[j].parent

    def moments(b):
        return [float(x) for x in np.diag(np.asarray(b.inertia, dtype=float))]

    massless = {i for i, b in enumerate(bodies) if b.mass == 0.0 and not any(moments(b))}
    out = []
    for i, b in enumerate(bodies):
        if b.joint == "fixed":
            continue
        alone = all(c in massless for c in below[i])
        if i in massless and alone:
            out.append((i, "mass", 0.0, f"body {b.name!r} has neither mass nor inertia (mass and I1, I2, I3 all 0)",
                        "give it mass or inertia"))
        elif b.joint in ("slider", "free") and b.mass == 0.0 and all(bodies[c].mass == 0.0 for c in below[i]):
            what = "its slider" if b.joint == "slider" else "its free joint's translation"
            out.append((i, "mass", 0.0, f"body {b.name!r} has no mass for {what} to move (mass 0 kg, and none in "
                        "the bodies below it)", "give it mass"))
        elif b.joint == "hinge" and alone:
            axis = np.asarray(b.axis, dtype=float)
            cm = np.asarray(b.cm, dtype=float)
            J = np.asarray(b.inertia, dtype=float)
            if float(axis @ J @ axis) + b.mass * float(cm @ cm - (cm @ axis) ** 2) == 0.0:
                across = [c for k, c in enumerate("xyz") if abs(axis[k]) < 1.0]
                pick = next((c for c in across if float(cm["xyz".index(c)]) != 0.0), across[0])
                out.append((i, f"cm_{pick}", float(cm["xyz".index(pick)]), f"body {b.name!r} has no moment of "
                            f"inertia about its hinge axis (its mass {b.mass:g} kg on the axis, cm = "
                            f"[{', '.join(f'{x:g}' for x in cm)}] m, and no moment of its own about it)",
                            "move its centre of mass off the axis or give it a moment of inertia about it"))
    return out


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


#: Joint coordinates per joint (the engine's gs_tree_ncoord).
_NCOORD = {"ball": 7, "free_rotation": 7, "hinge": 2, "slider": 2, "free": 13, "fixed": 0}


def tree_nx(bodies, orbit) -> int:
    """The joint coordinates of a tree's state (nx: every body's, then a circular orbit's anomaly)."""
    return sum(_NCOORD[b.joint] for b in bodies) + (1 if orbit is not None and orbit.radius is not None else 0)


def implicit_fits(bodies, orbit, contact: bool = False) -> bool:
    """The implicit methods (midpoint, energy_momentum) take the tree: their dense Newton matrix is sized by the
    state, and the engine takes them up to _engine.IMPLICIT_MAX integrated components (nx and the work integral);
    not with contact, whose friction law's kinks (the slip's direction, the contact opening) their Newton
    iterations do not converge through."""
    from .core import _engine

    return not contact and tree_nx(bodies, orbit) + 1 <= _engine.IMPLICIT_MAX


def _kernel_code(scene) -> int:
    """The engine's kernel code for the tree with its scene's parameters (gs_tree_kernel: the kind, + 8 where the
    gyrostat's splittings apply)."""
    from .core import _engine
    from .kernel_tree import tree_layout

    lay = tree_layout(scene)
    if len(lay.bodies) > _engine.TREE_SMALL:
        return 0
    y = lay.state().reshape(1, -1)
    p = lay.params(scene.g, scene.max_drift).reshape(1, -1)
    return int(_engine.tree_scalar(lay.desc, y, p, 2))


def tree_kernel(scene) -> str:
    """The right-hand side the engine picks for the tree with its scene's parameters (Model.dynamics_kernel)."""
    from .kernel_tree import TREE_KERNELS

    return TREE_KERNELS[_kernel_code(scene) & 7]


def split_fits(scene) -> bool:
    """The integrators 'splitting' and 'splitting4' take the tree with its scene's parameters: the engine's gyrostat
    (a hub on a ball joint carrying rotors) without joint springs or damping, whose motion splits into exact flows
    (core/engine/tree_kernels.h)."""
    return bool(_kernel_code(scene) & 8)


def split_refusal() -> str:
    """Why a tree is refused the integrator 'splitting' (the ConfigError's rule)."""
    return ("'rk4', 'dop853' or 'midpoint' for this tree: 'splitting' follows the exact flows of a gyrostat, a hub "
            "on a ball joint carrying rotors (axisymmetric leaves on hinges) without joint springs or damping, "
            "stops, couplings, springs, forces, contacts or an orbit")


def implicit_refusal(bodies, orbit, contact: bool = False) -> str:
    """Why a tree is refused the implicit methods (the ConfigError's rule): too large, or with contact."""
    from .core import _engine

    if contact:
        return ("'rk4', 'euler', 'adaptive' or 'dop853' for a scene with contact: 'midpoint' and 'energy_momentum' "
                "solve each step by Newton's method, which does not converge through the contact law's kinks (the "
                "friction's direction at the slip's stop, the contact opening)")
    return (f"'rk4', 'euler', 'adaptive' or 'dop853' for this tree: 'midpoint' and 'energy_momentum' take at most "
            f"{_engine.IMPLICIT_MAX - 1} joint coordinates (their Newton matrix is dense: its factorisation costs the "
            f"cube of the state's size), and this tree has {tree_nx(bodies, orbit)} ({len(bodies)} bodies)")
