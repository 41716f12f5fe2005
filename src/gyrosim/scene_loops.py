"""Closed loops and gears in a tree scene: ``[[loop]]`` tables (a point of one body held on a point of another, or of
the world) and ``[[gear]]`` tables (two joints' rates in a fixed ratio), DESIGN 4b and docs/scenes.md::

    [[loop]]
    name = "close"                   # names the outputs <loop>.residual, .rate_residual, .f_x..z (scene-wide)
    kind = "revolute"                # required: spherical (the points coincide), revolute (and axis_a, axis_b stay
                                     # aligned) or prismatic (b's point stays on the line through a's point along
                                     # axis_a, and the bodies' relative rotation stays as it starts)
    body_a = "coupler"               # a body of the scene or "world" (default "world"; not both "world")
    point_a = [0.35, 0, 0]           # m, body_a's frame (the world's for "world"); default [0, 0, 0]
    body_b = "rocker"
    point_b = [0.3, 0, 0]            # m, body_b's frame
    axis_a = [0, 0, 1]               # revolute, prismatic (required): body_a's frame (the world's), made unit
    axis_b = [0, 0, 1]               # revolute: body_b's frame, made unit (default: axis_a's components)

    [[gear]]
    name = "mesh"                    # names the parameter <gear>.ratio and the output <gear>.torque
    joints = ["pinion", "wheel"]     # two bodies on hinge or slider joints: their joints
    ratio = -3.0                     # rate of joints[0] = ratio x rate of joints[1]; finite, not 0

A prismatic loop holds the relative rotation ``R_a^T R_b`` the bodies have at the scene file's start state
(:func:`with_start_rotations`). A loop's geometry is structural (no variables); a gear's ratio is the parameter
``<gear>.ratio``, its sign fixed by the scene file (the turning sense is the mechanism's): every value of it, from the
scene file, ``--set``, start values, the FMUs or a sweep, is checked by :func:`ratio_range`.
"""

from __future__ import annotations

import math

import numpy as np

from .core import _engine
from .core.tree import LOOP_KINDS, Gear, Loop
from .errors import ConfigError
from .ranges import MAX_MAGNITUDE, Range

__all__ = ["loops_from_dict", "gears_from_dict", "with_start_rotations", "start_attitudes", "check_closed",
           "ratio_range", "ratio_rule", "gear_units", "LOOP_KEYS", "GEAR_KEYS", "LOOP_ROWS", "ROWS_MAX"]

LOOP_KEYS = ("name", "kind", "body_a", "point_a", "body_b", "point_b", "axis_a", "axis_b")
GEAR_KEYS = ("name", "joints", "ratio")
#: What each loop kind holds, as the messages say it.
_KIND_TEXT = {"spherical": "the points coincide", "revolute": "the points coincide and axis_a, axis_b stay aligned",
              "prismatic": "b's point stays on a's axis through a's point, the relative rotation as it starts"}
#: The constraint rows of each loop kind (a gear has 1, a contact up to 4): the engine solves at most ROWS_MAX at once
#: (gyrosim_tree.h GS_TREE_ROWS_MAX; 64 where the engine module does not export it).
LOOP_ROWS = {"spherical": 3, "revolute": 5, "prismatic": 5}
ROWS_MAX = _engine.TREE_ROWS_MAX
#: The joints a gear couples.
GEAR_JOINTS = ("hinge", "slider")


def _h():  # scene.py's helpers (imported late: scene.py imports this module)
    from . import scene

    return scene


def _tables(data: dict, kind: str, keys: tuple, names: list, taken: list, source: str, others: str):
    from .scene_tree import _element_tables

    return _element_tables(data, kind, keys, names, taken, source, others)


def _axis(t: dict, key: str, where: str, frame: str) -> np.ndarray:
    v = _h()._vec(t, key, 3, where)
    n = float(np.linalg.norm(v))
    if not n > 0:
        raise ConfigError(key, t[key], f"a nonzero vector in {frame} (it is made unit)", where=where)
    return v / n


def _frame(body: str) -> str:
    return "the world's frame" if body == "world" else f"body {body!r}'s frame"


def loops_from_dict(data: dict, bodies, taken: list, source: str) -> tuple:
    """The ``[[loop]]`` tables as :class:`~gyrosim.core.tree.Loop` (a prismatic loop's ``q0`` the identity until
    :func:`with_start_rotations`); names unique among the bodies and ``taken`` (every element named before)."""
    s = _h()
    names = [b.name for b in bodies]
    out = []
    for t, w, nm in _tables(data, "loop", LOOP_KEYS, names, taken, source,
                            "body, coupling, spring, force, shape, plane or loop"):
        kind = t.get("kind")
        kinds = ", ".join(f"{k} ({v})" for k, v in _KIND_TEXT.items())
        if kind is None:
            raise ConfigError("kind", None, f"one of {kinds} (this key is required)", where=w)
        if not isinstance(kind, str) or kind not in LOOP_KINDS:
            raise ConfigError("kind", kind, f"one of {kinds}{s.did_you_mean(str(kind), LOOP_KINDS, cutoff=0.5)}",
                              where=w)
        ends = []
        for side in ("a", "b"):
            bn = t.get(f"body_{side}", "world")
            if bn != "world" and bn not in names:
                raise ConfigError(f"body_{side}", bn, f"'world' or a body of the scene ({', '.join(names)})"
                                  f"{s.did_you_mean(str(bn), names + ['world'])}", where=w)
            pt = s._vec(t, f"point_{side}", 3, w) if f"point_{side}" in t else np.zeros(3)
            ends.append((bn, -1 if bn == "world" else names.index(bn), pt))
        (na, ia, pa), (nb, ib, pb) = ends
        if ia == ib:
            raise ConfigError("body_b", nb, f"a body other than body_a = {na!r} (a loop joins two bodies, or a body "
                              "and the world)", where=w)
        axis_a = axis_b = np.array([0.0, 0.0, 1.0])
        if kind == "spherical":
            for k in ("axis_a", "axis_b"):
                if k in t:
                    raise ConfigError(k, t[k], "left out of a spherical loop (its points coincide whatever the "
                                      "bodies' rotation; a revolute or prismatic loop takes axis_a)", where=w)
        else:
            if "axis_a" not in t:
                raise ConfigError("axis_a", None, f"a nonzero vector in {_frame(na)} (this key is required for a "
                                  f"{kind} loop: {_KIND_TEXT[kind]})", where=w)
            axis_a = _axis(t, "axis_a", w, _frame(na))
            if kind == "prismatic" and "axis_b" in t:
                raise ConfigError("axis_b", t["axis_b"], "left out of a prismatic loop (b's point slides along "
                                  "axis_a, and the bodies' relative rotation is held as it starts)", where=w)
            axis_b = _axis(t, "axis_b", w, _frame(nb)) if "axis_b" in t else axis_a.copy()
        out.append(Loop(nm, ia, ib, kind, pa, pb, axis_a, axis_b, np.array([1.0, 0.0, 0.0, 0.0])))
    return tuple(out)


def gear_units(bodies, g: Gear) -> tuple[str, str]:
    """The units of gear ``g``'s ``ratio`` (rate of a over rate of b: ``1`` between joints of one kind, ``m/rad``
    from a hinge b to a slider a, ``rad/m`` the other way) and of its ``torque`` (joint a's generalized force: N*m on
    a hinge, N on a slider)."""
    ka, kb = bodies[g.a].joint, bodies[g.b].joint
    ratio = "1" if ka == kb else ("m/rad" if ka == "slider" else "rad/m")
    return ratio, ("N" if ka == "slider" else "N.m")


def ratio_range(ratio: float) -> Range:
    """The values a gear's ratio may take: finite, at most 1e12 in size, of the scene file's sign (``ratio``'s; the
    turning sense is the mechanism's, and 0 is no gear): the one check at every door."""
    if ratio < 0:
        return Range(-MAX_MAGNITUDE, 0.0, exclusive_max=True)
    return Range(0.0, MAX_MAGNITUDE, exclusive_min=True)


def ratio_rule(bodies, g: Gear) -> str:
    """What a value of gear ``g``'s ratio must be, as the messages say it (the sign of its scene file's ``ratio``)."""
    sense = "against" if g.ratio < 0 else "with"
    return (f"{ratio_range(g.ratio).text(gear_units(bodies, g)[0])} (the sign is the scene file's: gear {g.name} "
            f"turns {bodies[g.a].name} {sense} {bodies[g.b].name})")


def gears_from_dict(data: dict, bodies, taken: list, source: str) -> tuple:
    """The ``[[gear]]`` tables as :class:`~gyrosim.core.tree.Gear`: two distinct bodies on hinge or slider joints,
    a finite ratio other than 0 (at most 1e12 in size); names unique among the bodies and ``taken``."""
    s = _h()
    names = [b.name for b in bodies]
    out = []
    for t, w, nm in _tables(data, "gear", GEAR_KEYS, names, taken, source,
                            "body, coupling, spring, force, shape, plane, loop or gear"):
        pair = t.get("joints")
        what = "two bodies [a, b] on hinge or slider joints (their joints: rate of a = ratio x rate of b)"
        if pair is None:
            raise ConfigError("joints", None, f"{what} (this key is required)", where=w)
        if not (isinstance(pair, list) and len(pair) == 2 and all(isinstance(x, str) for x in pair)):
            raise ConfigError("joints", pair, what, where=w)
        for x in pair:
            if x not in names:
                raise ConfigError("joints", pair, f"{what}; {x!r} is no body of the scene ({', '.join(names)})"
                                  f"{s.did_you_mean(x, names)}", where=w)
            joint = bodies[names.index(x)].joint
            if joint not in GEAR_JOINTS:
                raise ConfigError("joints", pair, f"{what}; body {x!r} has joint {joint!r}", where=w)
        if pair[0] == pair[1]:
            raise ConfigError("joints", pair, "two different bodies (a gear couples two joints)", where=w)
        ratio = s._num(t, "ratio", w, required=True)
        g = Gear(nm, names.index(pair[0]), names.index(pair[1]), ratio)
        unit = gear_units(bodies, g)[0]
        if ratio == 0.0 or abs(ratio) > MAX_MAGNITUDE:
            raise ConfigError("ratio", ratio, f"a finite number other than 0, at most {MAX_MAGNITUDE:g} in size, in "
                              f"{unit} (rate of {pair[0]} = ratio x rate of {pair[1]}; negative: they turn against "
                              "each other)", where=w)
        out.append(g)
    return tuple(out)


def check_closed(bodies, loops, gears, contacts: int, source: str) -> None:
    """What the engine's constraint solve takes. Loops and gears alone: any tree (beyond TREE_SMALL bodies or
    :data:`ROWS_MAX` rows the engine's heap build solves them). With rigid contacts too (their events run in the
    stack build): at most TREE_SMALL bodies and ROWS_MAX constraint rows at once (3 per spherical loop, 5 per
    revolute or prismatic one, 1 per gear, 4 per contact)."""
    if (not loops and not gears) or not contacts:
        return
    what = "loop" if loops else "gear"
    if len(bodies) > _engine.TREE_SMALL:
        raise ConfigError(what, f"{len(bodies)} bodies", f"a tree of at most {_engine.TREE_SMALL} bodies with closed "
                          "loops or gears beside rigid contacts", where=source)
    rows = sum(LOOP_ROWS[lp.kind] for lp in loops) + len(gears) + 4 * contacts
    if rows > ROWS_MAX:
        raise ConfigError(what, f"{rows} constraint rows", f"at most {ROWS_MAX} constraint rows solved at once beside "
                          "rigid contacts (a spherical loop has 3, a revolute or prismatic loop 5, a gear 1, a contact "
                          "4)", where=source)


def start_attitudes(bodies) -> np.ndarray:
    """(n_bodies, 4) every body's world attitude ``q_world`` (w, x, y, z) at the scene file's start state, from the
    engine's outputs."""
    from .core.tree import BODY_OUTPUTS, TreeLayout

    lay = TreeLayout(bodies)
    y = lay.state().reshape(1, -1)
    p = lay.params(0.0, 0.0).reshape(1, -1)
    _engine.tree_start(lay.desc, y, p)   # quaternions normalised (a zero one is the model's to refuse)
    out = np.empty((1, lay.nout))
    _engine.tree_outputs(lay.desc, y, p, out)
    qw = BODY_OUTPUTS.index("q_world_w")
    return np.array([out[0, lay.nx + len(BODY_OUTPUTS) * i + qw:lay.nx + len(BODY_OUTPUTS) * i + qw + 4]
                     for i in range(len(bodies))])


def with_start_rotations(loops, bodies) -> tuple:
    """The loops with every prismatic loop's ``q0`` set: the relative rotation ``conj(q_a) * q_b`` (R_a^T R_b) of
    its bodies' world attitudes at the scene file's start state (the world's is the identity), unit, ``w >= 0``."""
    if not any(lp.kind == "prismatic" for lp in loops):
        return tuple(loops)
    import dataclasses

    from .core.rotations import quat_conjugate, quat_multiply

    qs = start_attitudes(bodies)
    ident = np.array([1.0, 0.0, 0.0, 0.0])
    out = []
    for lp in loops:
        if lp.kind == "prismatic":
            qa = ident if lp.a < 0 else qs[lp.a]
            qb = ident if lp.b < 0 else qs[lp.b]
            q = quat_multiply(quat_conjugate(qa), qb)
            n = float(np.linalg.norm(q))
            q = q / n if math.isfinite(n) and n > 0 else ident
            lp = dataclasses.replace(lp, q0=q if q[0] >= 0 else -q)
        out.append(lp)
    return tuple(out)
