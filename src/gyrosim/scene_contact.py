"""Contact in a tree scene: ``[[shape]]`` tables (convex shapes on bodies) and ``[[plane]]`` tables (planes fixed in
the world with their contact law), DESIGN 4b and docs/scenes.md::

    [[shape]]
    name = "ball"                    # names the outputs: <shape>.gap, .normal_force, .friction_x..z, .slip_speed,
    body = "top"                     #   .contact_x..z, .mode (<shape>.<plane>.<quantity> with several planes)
    kind = "sphere"                  # sphere, ellipsoid, disk, cylinder, point
    center = [0, 0, 0.003]           # m, body frame (default the joint point)
    radius = 0.015                   # m: sphere, disk, cylinder
    semi_axes = [0.1, 0.02, 0.01]    # m: ellipsoid, along the shape's axes
    axis = [0, 0, 1]                 # body frame: a disk's or cylinder's axis
    length = 0.01                    # m: cylinder
    rotation = { zyz = [0, 0, 0] }   # the shape's axes in the body frame, as a joint's rotation

    [[plane]]
    name = "floor"
    point = [0, 0, 0]                # m, world
    normal = [0, 0, 1]               # world (made unit); the solid is on the side it points away from
    model = "rigid"                  # rigid (unilateral, impacts and lift-off as events; default) or compliant
    restitution = 0.0                # rigid: Newton's restitution of an impact
    stiffness = 1e6                  # compliant: Hunt-Crossley, N/m^1.5
    damping = 0.0                    # compliant: s/m
    friction = 0.3                   # Coulomb mu (inf: never slips, a rolling constraint; held as 1e12)
    friction_model = "coulomb"       # coulomb (sticking as a mode; rigid only; default) or regularized
    slip_velocity = 1e-3             # m/s: the regularized law's (and rolling resistance's) slip velocity
    spin_radius = 0.0                # m: Contensou spin friction (0: none)
    rolling_resistance = 0.0         # m: the lever of rolling resistance (0: none)

The plane's parameters are the scene's variables ``<plane>.<parameter>``; every value of them, from the scene file,
``--set``, the FMUs or a sweep, is checked by :data:`PLANE_RANGES`.
"""

from __future__ import annotations

import math

import numpy as np

from .core.tree import CONTACT_MODELS, FRICTION_MODELS, SHAPE_KINDS, Plane, Shape
from .errors import ConfigError
from .ranges import BOUNDED_NONNEGATIVE, MAX_MAGNITUDE, Range

__all__ = ["shapes_from_dict", "planes_from_dict", "PLANE_PARAMS", "PLANE_RANGES", "plane_variables"]

_SHAPE_KEYS = ("name", "body", "kind", "center", "radius", "semi_axes", "axis", "length", "rotation")
_PLANE_KEYS = ("name", "point", "normal", "model", "stiffness", "damping", "friction", "friction_model",
               "slip_velocity", "spin_radius", "rolling_resistance", "restitution")
#: Which dimensions each kind takes.
_KIND_KEYS = {"sphere": ("radius",), "ellipsoid": ("semi_axes",), "disk": ("radius", "axis"),
              "cylinder": ("radius", "axis", "length"), "point": ()}

_POSITIVE_BOUNDED = Range(0.0, MAX_MAGNITUDE, exclusive_min=True)
#: A plane's parameters: unit, description, default and allowed values (the one check at every door).
PLANE_PARAMS = {
    "stiffness": ("N/m1.5", "Hunt-Crossley contact stiffness (normal force k delta^1.5, delta the penetration)",
                  None, _POSITIVE_BOUNDED),
    "damping": ("s/m", "Hunt-Crossley contact damping (normal force times 1 + damping * penetration rate)", 0.0,
                BOUNDED_NONNEGATIVE),
    "friction": ("1", "Coulomb friction coefficient", 0.0, BOUNDED_NONNEGATIVE),
    "slip_velocity": ("m/s", "regularized friction's slip velocity (tanh(slip / slip_velocity) of Coulomb's force)",
                      1e-3, _POSITIVE_BOUNDED),
    "spin_radius": ("m", "Contensou spin friction's contact radius (0: none)", 0.0, BOUNDED_NONNEGATIVE),
    "rolling_resistance": ("m", "rolling resistance lever (torque normal_force * lever against the rolling)", 0.0,
                           BOUNDED_NONNEGATIVE),
    "restitution": ("1", "Newton's restitution of rigid impacts", 0.0, Range(0.0, 1.0)),
}
#: The allowed values of each plane parameter.
PLANE_RANGES = {k: v[3] for k, v in PLANE_PARAMS.items()}


def _h():  # scene.py's helpers (imported late: scene.py imports this module)
    from . import scene

    return scene


def _names(data: dict, kind: str, keys: tuple, taken: list, source: str):
    from .scene_tree import _element_tables

    return _element_tables(data, kind, keys, taken, [], source)


def _unit(v: np.ndarray, key: str, where: str) -> np.ndarray:
    n = float(np.linalg.norm(v))
    if n == 0.0:
        raise ConfigError(key, v.tolist(), "a nonzero vector (it is made unit)", where=where)
    return v / n


def _axes_with(axis: np.ndarray) -> np.ndarray:
    """A right-handed frame (columns) whose third axis is ``axis`` (unit)."""
    e = np.eye(3)[int(np.argmin(np.abs(axis)))]
    x = np.cross(e, axis)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(axis, x), axis])


def shapes_from_dict(data: dict, bodies: list, taken: list, source: str) -> tuple:
    """The ``[[shape]]`` tables as :class:`~gyrosim.core.tree.Shape` (names unique among bodies and elements)."""
    from .core.rotations import quat_to_matrix
    from .scene_tree import _rotation

    s = _h()
    out = []
    for t, w, nm in _names(data, "shape", _SHAPE_KEYS, bodies + list(taken), source):
        bn = t.get("body")
        if bn not in bodies:
            raise ConfigError("body", bn, f"a body of the scene ({', '.join(bodies)})"
                              f"{s.did_you_mean(str(bn), bodies)}", where=w)
        kind = t.get("kind")
        if kind not in SHAPE_KINDS:
            raise ConfigError("kind", kind, f"one of {', '.join(SHAPE_KINDS)}", where=w)
        for k in ("radius", "semi_axes", "axis", "length"):
            if k in t and k not in _KIND_KEYS[kind]:
                raise ConfigError(k, t[k], f"left out of a {kind} (a {kind} takes "
                                  f"{', '.join(_KIND_KEYS[kind]) or 'no dimensions'})", where=w)
        center = s._vec(t, "center", 3, w) if "center" in t else np.zeros(3)
        S = quat_to_matrix(_rotation(t["rotation"], w)) if "rotation" in t else np.eye(3)
        dims = (0.0, 0.0, 0.0)
        if kind in ("sphere", "disk", "cylinder"):
            r = s._num(t, "radius", w, lo=0.0, lo_open=True, required=True)
            length = s._num(t, "length", w, lo=0.0, lo_open=True, required=True) if kind == "cylinder" else 0.0
            dims = (r, length, 0.0)
        elif kind == "ellipsoid":
            ax = s._vec(t, "semi_axes", 3, w)
            if np.any(ax <= 0.0):
                raise ConfigError("semi_axes", ax.tolist(), "three lengths > 0 (m)", where=w)
            dims = tuple(float(x) for x in ax)
        if kind in ("disk", "cylinder"):
            S = S @ _axes_with(_unit(s._vec(t, "axis", 3, w), "axis", w) if "axis" in t else np.array([0, 0, 1.0]))
        out.append(Shape(nm, bodies.index(bn), kind, center, S, dims))
    return tuple(out)


def planes_from_dict(data: dict, taken: list, source: str) -> tuple:
    """The ``[[plane]]`` tables as :class:`~gyrosim.core.tree.Plane`."""
    s = _h()
    out = []
    for t, w, nm in _names(data, "plane", _PLANE_KEYS, list(taken), source):
        model = t.get("model", "rigid")
        if model not in CONTACT_MODELS:
            raise ConfigError("model", model, "'rigid' (impacts and lift-off as events) or 'compliant' "
                              "(Hunt-Crossley)", where=w)
        fmodel = t.get("friction_model", "coulomb" if model == "rigid" else "regularized")
        if fmodel not in FRICTION_MODELS:
            raise ConfigError("friction_model", fmodel, "'coulomb' or 'regularized'", where=w)
        if fmodel == "coulomb" and model == "compliant":
            raise ConfigError("friction_model", fmodel, "'regularized' on a compliant plane (Coulomb's sticking is "
                              "a mode of the rigid law: model = 'rigid')", where=w)
        for k in ("stiffness", "damping"):
            if k in t and model == "rigid":
                raise ConfigError(k, t[k], "left out of a rigid plane (a compliant plane's: model = 'compliant')",
                                  where=w)
        point = s._vec(t, "point", 3, w) if "point" in t else np.zeros(3)
        normal = _unit(s._vec(t, "normal", 3, w), "normal", w) if "normal" in t else np.array([0.0, 0.0, 1.0])
        vals = {}
        for k, (unit, _, default, rng) in PLANE_PARAMS.items():
            if k == "friction" and t.get(k) == math.inf:
                if fmodel != "coulomb":
                    raise ConfigError(k, t[k], "a finite coefficient with friction_model = 'regularized' (inf: "
                                      "never slips, Coulomb's sticking: friction_model = 'coulomb')", where=w)
                vals[k] = MAX_MAGNITUDE   # never slips: the cone's margin is 1e12 times the normal force
                continue
            if k == "stiffness" and model == "rigid":
                vals[k] = 0.0
                continue
            v = s._num(t, k, w, default, required=default is None)
            if v not in rng:
                raise ConfigError(k, v, rng.text(unit), where=w)
            vals[k] = v
        out.append(Plane(nm, point, normal, model, fmodel, **vals))
    return tuple(out)


def plane_parameters(pl) -> dict:
    """The parameters plane ``pl``'s law has, by name -> (unit, description, default, range): a rigid plane's
    restitution, a compliant one's stiffness and damping, the slip velocity where a law uses it (regularized
    friction, rolling resistance), and friction, spin radius and rolling resistance for every plane."""
    out = {}
    for k, v in PLANE_PARAMS.items():
        if k == "restitution" and pl.model != "rigid" or k in ("stiffness", "damping") and pl.model != "compliant":
            continue
        if k == "slip_velocity" and pl.friction_model != "regularized" and not pl.rolling_resistance:
            continue
        out[k] = v
    return out


def plane_variables(planes) -> list:
    """The planes' parameters as variables ``<plane>.<parameter>``."""
    from .variables import Variable

    V = []
    for pl in planes:
        for k, (unit, desc, _, rng) in plane_parameters(pl).items():
            V.append(Variable(f"{pl.name}.{k}", "parameter", "fixed", "Real", unit, f"{desc}, plane {pl.name}",
                              float(getattr(pl, k)), **rng.fields()))
    return V
