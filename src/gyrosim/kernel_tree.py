"""The model's operations on the tree kernel: bodies joined by joints (docs/trees.md), integrated by the
articulated-body algorithm (``core/engine/tree.c``).

:class:`TreeKernel` maps a tree scene's variables (``rotor.angle``, or ``angle`` with ``body="rotor"``) onto the C
engine's tree rows; every step is one call of the engine (``gs_tree_advance``), which the FMUs compile too. Its
functions are the :class:`gyrosim.model.Model`'s own (``self`` is the model): the model calls the kernel its scene
was set up with.
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from .core import _engine
from .core.tree import (
    BODY_OUTPUTS,
    BODY_SLOTS,
    CONTACT_OUTPUTS,
    GEAR_OUTPUTS,
    INPUT_SLOTS,
    LOOP_OUTPUTS,
    ORBIT_BODY_OUTPUTS,
    ORBIT_COORD,
    ORBIT_OUTPUTS,
    PLANE_SLOTS,
    SCENE_OUTPUTS,
    TreeLayout,
)
from .errors import ConfigError, IntegrationError
from .ranges import ANY, BOUNDED, BOUNDED_NONNEGATIVE, NONNEGATIVE, POSITIVE, Range
from .scene import TREE_INTEGRATORS, Scene, did_you_mean
from .scene_tree import NONNEGATIVE_PARAMS, body_parameters
from .variables import Variable

__all__ = ["TreeKernel", "tree_variables", "tree_output_names"]

_METHOD_CODES = {name: code for code, name in enumerate(_engine.METHODS)}
#: The tree's methods of equal steps of at most max_step.
_FIXED = ("euler", "rk4", "midpoint", "energy_momentum", "splitting", "splitting4")
#: The right-hand side's kernels the engine picks for a tree at set-up (core/engine/tree_kernels.h), by code.
TREE_KERNELS = ("articulated_body", "gyrostat", "gimbal")
#: The implicit methods (implicit.c): their trajectories keep the Newton matrix from interval to interval, so they
#: are not the bits of a loop of steps (each step builds its own).
_IMPLICIT = ("midpoint", "energy_momentum")
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
    "displacement": ("m", "slider displacement along its axis"),
    "velocity": ("m/s", "slider velocity along its axis"),
}
#: Every body's outputs (BODY_OUTPUTS) by stem: unit and description ({} the component).
_BODY_OUT_META = {
    "q_world": ("1", "attitude in the world, {} part (body to world)"),
    "r_world": ("m", "position of the body frame's origin in the world, {}"),
    "v_world": ("m/s", "velocity of the body frame's origin in the world, {}"),
}
_SPRING_META = {"stiffness": ("N/m", "spring stiffness"), "rest_length": ("m", "spring rest length"),
                "damping": ("N.s/m", "spring damping (along the line between its points)")}
_SCENE_OUT_META = {
    "energy": ("J", "kinetic plus potential energy of the whole tree (gravity and springs)"),
    "energy_error": ("J", "work-energy balance E(t) - E(0) - W_inputs(t) + W_damping(t)"),
    "L_x": ("kg.m2/s", "total angular momentum about the world origin, world x"),
    "L_y": ("kg.m2/s", "total angular momentum about the world origin, world y"),
    "L_z": ("kg.m2/s", "total angular momentum about the world origin, world z"),
}


_ORBIT_OUT_META = {
    "orbit_r_x": ("m", "position of the orbit point from the central body, world x (circular: the tree's reference "
                  "point; Kepler: the tree's centre of mass)"),
    "orbit_r_y": ("m", "position of the orbit point from the central body, world y"),
    "orbit_r_z": ("m", "position of the orbit point from the central body, world z"),
    "orbit_v_x": ("m/s", "velocity of the orbit point, world x"),
    "orbit_v_y": ("m/s", "velocity of the orbit point, world y"),
    "orbit_v_z": ("m/s", "velocity of the orbit point, world z"),
}


def tree_output_names(scene: Scene) -> list[str]:
    """The output columns of a tree scene's engine rows: ``<body>.<coordinate>`` (and a circular orbit's
    ``orbit_anomaly``), ``<body>.q_world_*``, the scene-wide ``energy``, ``energy_error``, ``L_x``, ``L_y``,
    ``L_z``; on an orbit then ``<body>.q_orbit_*`` and ``orbit_r_*``, ``orbit_v_*``; then the contacts' outputs, the
    closed loops' ``<loop>.residual``, ... and the gears' ``<gear>.torque`` (scene-wide)."""
    name = scene.var_name
    out = []
    for body in scene.tree:
        out += [name(body.name, c) for c in body.coords]
    orbit = getattr(scene, "orbit", None)
    if orbit is not None and orbit.circular:
        out.append(ORBIT_COORD)
    for body in scene.tree:
        out += [name(body.name, c) for c in BODY_OUTPUTS]
    out += list(SCENE_OUTPUTS)
    if orbit is not None:
        for body in scene.tree:
            out += [name(body.name, c) for c in ORBIT_BODY_OUTPUTS]
        out += list(ORBIT_OUTPUTS)
    for h, stem in contact_stems(scene):
        out += [name(scene.tree[h.body].name, f"{stem}.{c}") for c in CONTACT_OUTPUTS]
    for lp in getattr(scene, "loops", ()):
        out += [f"{lp.name}.{c}" for c in LOOP_OUTPUTS]
    for gr in getattr(scene, "gears", ()):
        out += [f"{gr.name}.{c}" for c in GEAR_OUTPUTS]
    return out


def contact_stems(scene) -> list:
    """``(shape, stem)`` per contact in the engine's order: the stem ``<shape>`` with one plane,
    ``<shape>.<plane>`` otherwise (the body prefix comes by the naming rule)."""
    return [(h, stem) for h, _, stem in contacts_of(scene)]


def contacts_of(scene) -> list:
    """``(shape, plane, stem)`` per contact in the engine's order (shape-major: every shape meets every plane)."""
    planes = getattr(scene, "planes", ())
    return [(h, pl, h.name if len(planes) == 1 else f"{h.name}.{pl.name}") for h in getattr(scene, "shapes", ())
            for pl in planes]


#: The contact outputs' units and descriptions.
_CONTACT_META = {
    "gap": ("m", "distance of the shape above the plane (negative: penetration)"),
    "normal_force": ("N", "normal force of the plane on the shape"),
    "friction_x": ("N", "friction force of the plane on the shape, world x"),
    "friction_y": ("N", "friction force of the plane on the shape, world y"),
    "friction_z": ("N", "friction force of the plane on the shape, world z"),
    "slip_speed": ("m/s", "speed of the body's point at the contact along the plane"),
    "contact_x": ("m", "contact point (the shape's point deepest along the plane's normal), world x"),
    "contact_y": ("m", "contact point, world y"),
    "contact_z": ("m", "contact point, world z"),
    "mode": ("1", "contact mode: 0 apart, 1 sliding, 2 rolling, 3 resting"),
    "jellett": ("kg.m3/s", "Jellett's integral L . rho (L about the centre of mass, rho the contact point from it): "
                "constant for a sphere without spin friction"),
}
#: The closed loops' outputs (LOOP_OUTPUTS): unit and description (DESIGN 4b).
_LOOP_META = {
    "residual": ("m", "position residual: the points' distance (revolute, prismatic: with the axes' misalignment "
                 "times the loop's length scale)"),
    "rate_residual": ("m/s", "rate residual: the constraint rows' velocities (angular ones times the loop's length "
                      "scale)"),
    "f_x": ("N", "reaction force of the loop on body_b, world x"),
    "f_y": ("N", "reaction force of the loop on body_b, world y"),
    "f_z": ("N", "reaction force of the loop on body_b, world z"),
}
#: The gears' outputs (GEAR_OUTPUTS): description (the unit is joint a's generalized force: scene_loops.gear_units).
_GEAR_META = {"torque": "generalized force of the gear on joint a (N*m on a hinge, N on a slider; on joint b -ratio "
                        "times it)"}


def _body_param_value(b, name: str) -> float:
    if name.startswith(("stiffness_", "joint_damping_")):
        v = b.ball_stiffness if name.startswith("stiffness_") else b.ball_damping
        return float(v["xyz".index(name[-1])])
    if name == "rest_displacement":
        return float(b.rest_angle)
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
    """Every variable of a tree scene by its full name (``<body>.<name>``, bare in a scene of one body;
    scene-wide names bare)."""
    from .scene import INTEGRATORS

    gdir = tuple(scene.gravity_dir)
    along = "along -z" if gdir == (0.0, 0.0, -1.0) else "along the scene's gravity direction " + \
        "(" + ", ".join(f"{x:.6g}" for x in gdir) + ")"
    V = [Variable("g", "parameter", "fixed", "Real", "m/s2", f"gravitational acceleration {along}", float(scene.g),
                  **BOUNDED_NONNEGATIVE.fields())]
    orbit = scene.orbit
    if orbit is not None:
        V.append(Variable("orbit_mu", "parameter", "fixed", "Real", "m3/s2",
                          "gravitational parameter of the central body (gravity gradient" +
                          (", tidal forces)" if orbit.circular else ", central force)"), float(orbit.mu),
                          **POSITIVE.fields()))
        if orbit.circular:
            V.append(Variable("orbit_radius", "parameter", "fixed", "Real", "m",
                              "radius of the circular orbit of the tree's reference point", float(orbit.radius),
                              **POSITIVE.fields()))
    for a in scene.aliases:
        V.append(Variable(a.name, "parameter", "fixed", "Real", a.unit, a.description, float(a.value),
                          **a.range.fields()))
    for name, (_, _, k) in zip(scene.coupling_names, scene.couplings):
        V.append(Variable(name, "parameter", "fixed", "Real", "N.m/rad", "torsion spring between two hinges",
                          float(k), **NONNEGATIVE.fields()))
    for sp in scene.springs:
        ends = " and ".join(scene.tree[i].name if i >= 0 else "the world" for i in (sp.a, sp.b))
        for k, (unit, desc) in _SPRING_META.items():
            V.append(Variable(f"{sp.name}.{k}", "parameter", "fixed", "Real", unit, f"{desc}, between {ends}",
                              float(getattr(sp, k)), **NONNEGATIVE.fields()))
    V += [Variable("integrator", "parameter", "fixed", "String", "",
                   "integrator: " + ", ".join(TREE_INTEGRATORS) + " (a tree; " +
                   ", ".join(i for i in INTEGRATORS if i not in TREE_INTEGRATORS) + " solve one body)",
                   scene.integrator),
          Variable("max_step", "parameter", "fixed", "Real", "s",
                   "largest internal step; euler and rk4 take h/max_step substeps rounded up", float(scene.max_step),
                   **POSITIVE.fields()),
          Variable("max_drift", "parameter", "fixed", "Real", "1",
                   "relative drift of the energy balance and the angular momentum beyond which a step counts as "
                   "blown up (0: off)", float(scene.max_drift), **NONNEGATIVE.fields())]
    for b in scene.tree:
        pre = "" if len(scene.tree) == 1 else f"{b.name}."  # Scene.var_name's rule
        params = body_parameters(b)
        for n, (unit_n, desc) in params.items():
            rng = Range(0.0, 1.0) if n == "restitution" else NONNEGATIVE if n in NONNEGATIVE_PARAMS else ANY
            V.append(Variable(pre + n, "parameter", "fixed", "Real", unit_n, desc, _body_param_value(b, n),
                              **rng.fields()))
        if b.motor_input and b.joint == "slider":
            V.append(Variable(pre + "motor_force", "input", "continuous", "Real", "N",
                              "motor force along the slider axis (on this body; its reaction on the parent)", b.motor0,
                              **BOUNDED.fields()))
        elif b.motor_input:
            V.append(Variable(pre + "motor_torque", "input", "continuous", "Real", "N.m",
                              "motor torque about the hinge axis (on this body; its reaction on the parent)", b.motor0,
                              **BOUNDED.fields()))
        for f in scene.forces:
            if scene.tree[f.body] is not b:
                continue
            for c in "xyz":
                V.append(Variable(pre + f"{f.name}.f_{c}", "input", "continuous", "Real", "N",
                                  f"force {f.name} at ({', '.join(f'{x:.6g}' for x in f.point)}) m of the body, "
                                  f"{'world' if f.world else 'body'} {c}, held over each step", 0.0,
                                  **BOUNDED.fields()))
        if b.torque_input:
            for n in ("tau_x", "tau_y", "tau_z"):
                V.append(Variable(pre + n, "input", "continuous", "Real", "N.m",
                                  f"external torque about body {n[-1]}, held over each step", 0.0,
                                  **BOUNDED.fields()))
        start = {"q": list(b.q0), "omega": list(b.omega0), "r": list(b.r0), "v": list(b.v0)}
        for c in b.coords:
            unit, desc = _COORD_META[c]
            if b.parent >= 0 and c[:2] in ("r_", "v_"):   # a free joint below a body: relative to its parent
                desc = (f"{'position' if c[0] == 'r' else 'velocity'} of the body's origin relative to its joint "
                        f"point (velocity: to the parent), parent frame {c[-1]}")
            if c in ("angle", "rate", "displacement", "velocity"):
                s = float(b.angle0 if c in ("angle", "displacement") else b.rate0)
            else:
                head, tail = c.rsplit("_", 1)
                s = float(start[head]["wxyz".index(tail) if head == "q" else "xyz".index(tail)])
            bound = {} if c.startswith("q_") else BOUNDED.fields()   # a quaternion is normalised at the start
            V.append(Variable(pre + c, "output", "continuous", "Real", unit, desc, s, **bound))
        for c in BODY_OUTPUTS:
            unit, desc = _BODY_OUT_META[c[:-2]]
            V.append(Variable(pre + c, "output", "continuous", "Real", unit, desc.format(c[-1]), None))
        if orbit is not None:
            for c in ORBIT_BODY_OUTPUTS:
                V.append(Variable(pre + c, "output", "continuous", "Real", "1",
                                  f"attitude in the orbit frame (local vertical, local horizontal), {c[-1]} part "
                                  "(body to orbit frame, w >= 0)", None))
    if orbit is not None and orbit.circular:
        V.append(Variable(ORBIT_COORD, "output", "continuous", "Real", "rad",
                          "anomaly of the circular orbit (the orbit point at radius (cos, sin, 0)), unwrapped",
                          float(orbit.anomaly)))
    if scene.shapes:
        from .scene_contact import plane_variables

        V += plane_variables(scene.planes)
        for h, stem in contact_stems(scene):
            pre = "" if len(scene.tree) == 1 else f"{scene.tree[h.body].name}."
            against = f" (shape {h.name}, plane {stem.split('.')[-1] if '.' in stem else scene.planes[0].name})"
            for c in CONTACT_OUTPUTS:
                unit, desc = _CONTACT_META[c]
                V.append(Variable(f"{pre}{stem}.{c}", "output", "continuous", "Real", unit, desc + against, None))
    V += loop_variables(scene)
    for n, (unit, desc) in _SCENE_OUT_META.items():
        V.append(Variable(n, "output", "continuous", "Real", unit, desc, None))
    if orbit is not None:
        for n, (unit, desc) in _ORBIT_OUT_META.items():
            V.append(Variable(n, "output", "continuous", "Real", unit, desc, None))
    return {v.name: v for v in V}


def loop_variables(scene: Scene) -> list[Variable]:
    """The closed loops' and the gears' variables: each gear's parameter ``<gear>.ratio`` (its range the scene file's
    sign: scene_loops.ratio_range), then the loops' outputs ``<loop>.residual``, ``.rate_residual``, ``.f_x..z`` and
    the gears' ``<gear>.torque`` (scene-wide names, in the engine's order)."""
    from .scene_loops import gear_units, ratio_range

    V = []
    tree = scene.tree
    for gr in scene.gears:
        a, b = tree[gr.a].name, tree[gr.b].name
        V.append(Variable(f"{gr.name}.ratio", "parameter", "fixed", "Real", gear_units(tree, gr)[0],
                          f"gear ratio: rate of {a}'s {tree[gr.a].joint} = ratio x rate of {b}'s {tree[gr.b].joint}",
                          float(gr.ratio), **ratio_range(gr.ratio).fields()))
    for lp in scene.loops:
        a, b = (tree[i].name if i >= 0 else "the world" for i in (lp.a, lp.b))
        ends = f" ({lp.kind} loop {lp.name}: body_a {a}, body_b {b})"
        for c in LOOP_OUTPUTS:
            unit, desc = _LOOP_META[c]
            V.append(Variable(f"{lp.name}.{c}", "output", "continuous", "Real", unit, desc + ends, None))
    for gr in scene.gears:
        for c in GEAR_OUTPUTS:
            V.append(Variable(f"{gr.name}.{c}", "output", "continuous", "Real", gear_units(tree, gr)[1],
                              f"{_GEAR_META[c]} (gear {tree[gr.a].name}:{tree[gr.b].name})", None))
    return V


#: The health monitor's scales in a tree's state row, after its nx coordinates (gyrosim_tree.h: y[nx + 1] the energy
#: scale S0, y[nx + 5] the momentum scale).
_MON_ESCALE = 1
_MON_LSCALE = 5

_BODY_COLS = {**BODY_SLOTS, **INPUT_SLOTS}


def element_columns(sc, layout: TreeLayout) -> dict[str, int]:
    """The elements' variables (:meth:`Scene.element_variables`) by full name -> their column in a parameter row."""
    out = {}
    for name, (kind, e, short) in sc.element_variables().items():
        if kind == "spring":
            out[name] = layout.spring_offset(e) + {"stiffness": _engine.SPR_K, "rest_length": _engine.SPR_L0,
                                                   "damping": _engine.SPR_C}[short]
        elif kind == "plane":
            out[name] = layout.plane_offset(e) + PLANE_SLOTS[short]
        elif kind == "gear":
            out[name] = layout.gear_offset(e) + _engine.GR_RATIO
        else:
            out[name] = layout.force_offset(e) + _engine.FRC_F + "xyz".index(short[-1])
    return out


def alias_targets(sc, layout: TreeLayout, a) -> list[tuple[int, float, bool, str]]:
    """Where scene parameter ``a`` writes: ``(column, factor, must be >= 0, target name)`` per target (a body's
    parameter, or a spring's: ``spring.<parameter>`` in ``a.sets`` with the spring's index)."""
    out = []
    for i, pn, f in a.sets:
        if pn.startswith("spring."):
            short = pn[7:]
            col = layout.spring_offset(i) + {"stiffness": _engine.SPR_K, "rest_length": _engine.SPR_L0,
                                             "damping": _engine.SPR_C}[short]
            out.append((col, f, True, f"{sc.springs[i].name}.{short}"))
        else:
            out.append((layout.body_offset(i) + _BODY_COLS[pn], f, pn in NONNEGATIVE_PARAMS,
                        f"{sc.tree[i].name}.{pn}"))
    return out


def tree_layout(sc) -> TreeLayout:
    """The engine layout of a tree scene (cached with the scene's tables)."""
    return _scene_tables(sc)[0]


#: A scene's engine layout, variable table and output names, built once per Scene object (a Scene is frozen; the
#: tables only describe it): the set-up of a short run is mostly building them.
_TABLES: dict[int, tuple] = {}


def _scene_tables(sc) -> tuple:
    """(layout, variables, output names, output index) of the scene, from the cache (keyed by the object's identity,
    dropped with the object)."""
    key = id(sc)
    hit = _TABLES.get(key)
    if hit is not None and hit[0]() is sc:
        return hit[1:]
    names = tree_output_names(sc)
    layout = TreeLayout(sc.tree, sc.couplings, sc.orbit, springs=sc.springs, forces=sc.forces,
                        gravity_dir=sc.gravity_dir, shapes=sc.shapes, planes=sc.planes,
                        loops=getattr(sc, "loops", ()), gears=getattr(sc, "gears", ()))
    tables = (weakref.ref(sc), layout, tree_variables(sc), tuple(names), {n: i for i, n in enumerate(names)},
              element_columns(sc, layout))
    _TABLES[key] = tables
    weakref.finalize(sc, _TABLES.pop, key, None)
    return tables[1:]


class TreeKernel:
    """The tree kernel's operations of a :class:`~gyrosim.model.Model` (``self`` is the model).

    Variables are named ``<body>.<name>`` (``rotor.angle``, ``wheel_x.motor_torque``); the scene-wide ones bare
    (``energy``, ``L_z``, ``g``, ``integrator``). ``set``, ``get`` and ``outputs`` take the full name, or the body's
    own name with ``body=``.

    A scene with ``systems = k`` (the sweeps' replicas) holds k copies of the tree, stepped in one engine call:
    ``set`` sets every copy, ``set_many`` one value per copy, ``outputs_array`` and ``trajectory`` have a row per
    copy.

    Examples
    --------
    >>> from gyrosim import Model
    >>> m = Model("double_pendulum", parameters={"integrator": "rk4"})
    >>> m.step(0.01)
    >>> round(m.get("upper.angle"), 6) < 1.0
    True
    """

    #: what one row of the model's state is (Model.set_many's messages)
    SYSTEM = "copy"

    #: result rows come from whole output rows (``trajectory``), not written by the engine itself
    ROWS_DIRECT = False

    def setup(self) -> None:
        """The model's engine rows for the scene's tree (``systems`` copies of it)."""
        sc = self.scene
        self.layout, variables, self._out_names, self._out_index, self._element_cols = _scene_tables(sc)
        self.variables = dict(variables)
        self.body_names = sc.body_names
        self.n_bodies = len(self.body_names)
        self._n_systems = k = max(1, int(getattr(sc, "systems", 1)))
        self._index = {b: i for i, b in enumerate(self.body_names)}
        self._bodies = list(sc.tree)
        self._alias_names = [a.name for a in sc.aliases]
        self._alias_vals = np.tile(np.array([a.value for a in sc.aliases], dtype=float), (k, 1))
        self._pp = np.tile(self.layout.params(float(sc.g), float(sc.max_drift)), (k, 1))  # the parameters as set
        self._y = np.tile(self.layout.state(), (k, 1))
        self._hint = np.zeros(k)
        self._stats = np.zeros((k, 3), dtype=np.int64)
        self._status = np.zeros(k, dtype=np.int32)
        self._p = None  # the parameters the running state was started or moved with
        self._defer_together = False  # Model.set_values: several values set, then checked together

    def _replicable(self) -> bool:
        """Never: a tree model's rows are its own (gyrosim.trajectory.Run keeps no replica)."""
        return False

    def _trajectory(self, dt, n, angles: bool, momentum: bool, status, restore: bool) -> np.ndarray:
        """:meth:`trajectory` (``restore`` is the one-body kernel's: a tree's state is always kept)."""
        return self.trajectory(dt, n, angles=angles, momentum=momentum, status=status)

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
        return self.scene.var_name(body, name)

    def _var(self, name) -> Variable:
        v = self.variables.get(name)
        if v is None:
            raise ConfigError("variable", name, f"a variable of scene {self.scene.name!r}"
                              f"{did_you_mean(name, self.variables)}: " + ", ".join(list(self.variables)[:40]))
        return v

    def _columns(self, name: str) -> list:
        """Where a parameter or input lives in a parameter row: [(column, factor), ...]."""
        if name == "g":
            return [(_engine.TP_G, 1.0)]
        if name == "orbit_mu":
            return [(_engine.TP_MU, 1.0)]
        if name == "orbit_radius":
            return [(_engine.TP_ORBIT_R, 1.0)]
        if name in self._alias_names:
            a = self.scene.aliases[self._alias_names.index(name)]
            return [(col, f) for col, f, _, _ in alias_targets(self.scene, self.layout, a)]
        if name in self.scene.coupling_names:
            return [(self.layout.body_offset(self.n_bodies) + self.scene.coupling_names.index(name), 1.0)]
        if name in self._element_cols:
            return [(self._element_cols[name], 1.0)]
        bi, short = self.scene.split_name(name)
        return [(self.layout.body_offset(bi) + _BODY_COLS[short], 1.0)]

    def _check_value(self, name: str, v: Variable, x: np.ndarray) -> None:
        """Every value of ``x`` finite and within the variable's range (a scene parameter's: its scene file's
        min/max narrowed by its targets' rules), or a ConfigError naming the variable, the value and the range."""
        bad = ~v.range.contains(x)
        if bad.any():
            raise ConfigError(name, float(x[np.flatnonzero(bad)[0]]), TreeKernel._rule(self, name, v))

    def _rule(self, name: str, v: Variable) -> str:
        """What a value of variable ``name`` must be, as the messages say it."""
        gears = {f"{gr.name}.ratio": gr for gr in getattr(self.scene, "gears", ())}
        if name in gears:
            from .scene_loops import ratio_rule

            return ratio_rule(self.scene.tree, gears[name])
        return v.range.text(v.unit) + (f" (the range of scene parameter {name})" if name in self._alias_names
                                       else "")

    def _together(self) -> None:
        """The values that must hold together, as the engine checks them wherever values enter (gs_tree_check: the
        FMUs' initialisation too): a joint's stops in order and an impact-stopped joint within them. A ConfigError
        with the scene file's message where they do not (scene_tree's stops)."""
        bad = _engine.tree_check(self.layout.desc, self._y, self._pp)
        if bad is None:
            return
        code, c, slot, lo_slot, hi_slot = bad
        pp = self._pp[c]

        def param(k: int) -> tuple[str, str]:
            b = max(i for i in range(self.n_bodies) if self.layout.body_offset(i) <= k)
            short = "lower" if k - self.layout.body_offset(b) == _engine.TB_LO else "upper"
            full = self.scene.var_name(self.body_names[b], short)
            return full, self.variables[full].unit

        if code == _engine.TREE_BAD_CONTACT:   # slot: the contact; its gap from the outputs of this state
            from .core.tree import CONTACT_OUTPUTS

            h, pl, stem = contacts_of(self.scene)[slot]
            out = np.zeros((1, self.layout.nout))
            _engine.tree_outputs(self.layout.desc, self._y[c:c + 1], self._pp[c:c + 1], out)
            at = self.layout.nout - len(CONTACT_OUTPUTS) * len(contacts_of(self.scene)) + \
                len(CONTACT_OUTPUTS) * slot + CONTACT_OUTPUTS.index("gap")
            gap = self.scene.var_name(self.body_names[h.body], f"{stem}.gap")
            tol = 1e-9 + 1e-6 * max(h.dims)   # contact_events.h start_tolerance: nearer, put on the plane
            raise ConfigError(gap, float(out[0, at]), f"a start on or above plane {pl.name} (a gap >= -{tol:.3g} m, "
                              f"put on the plane; shape {h.name} starts inside it: move the body's start position "
                              "or attitude)")
        if code == _engine.TREE_BAD_LOOP:   # slot: the loop
            lp = self.scene.loops[slot]
            _, res = _engine.tree_loop_open(self.layout.desc, self._y[c:c + 1], self._pp[c:c + 1])
            raise ConfigError(f"{lp.name}.residual", res, "a start from which the loop closes (its points, and "
                              "its axes, brought together by the least mass-weighted move of the joints; this one "
                              "stays open: set the joints' start angles of a closed position)")
        if code == _engine.TREE_BAD_STOPS:
            (hi, unit), (lo, _) = param(slot), param(lo_slot)
            raise ConfigError(hi, float(pp[slot]), f"a number above {lo} = {float(pp[lo_slot])!r} {unit}")
        (b, short), = [key for key, k in self.layout.coord_slots.items() if k == slot]
        coord = self.scene.var_name(self.body_names[b], short)
        lo = float(pp[lo_slot]) if lo_slot >= 0 else -math.inf
        hi = float(pp[hi_slot]) if hi_slot >= 0 else math.inf
        raise ConfigError(coord, float(self._y[c, slot]), f"a start within the impact stops [{lo}, {hi}] "
                          f"{self.variables[coord].unit}")

    def _assign(self, name: str, v: Variable, x: np.ndarray) -> None:
        """Set parameter/input/start ``name`` to ``x`` (one value per system); values that must hold together
        checked at once (:meth:`_together`), unless the model sets several together (``Model.set_values``): a
        refused value leaves the model as it was."""
        TreeKernel._check_value(self, name, v, x)
        if self._defer_together or (v.causality == "input" and name not in self._alias_names):
            TreeKernel._assign_unchecked(self, name, v, x)
            return
        saved = (self._pp.copy(), self._y.copy(), self._alias_vals.copy(), self._initialized, self._state_dirty)
        TreeKernel._assign_unchecked(self, name, v, x)
        try:
            TreeKernel._together(self)
        except ConfigError:
            self._pp, self._y, self._alias_vals, self._initialized, self._state_dirty = saved
            self._out = None
            raise

    def _assign_unchecked(self, name: str, v: Variable, x: np.ndarray) -> None:
        if v.causality == "output":
            if v.start is None:
                raise ConfigError(name, float(x[0]), "a parameter, an input or a joint's start state; "
                                  f"{name} is a derived output")
            self._y[:, self.layout.coord_slots[self.scene.split_name(name)]] = x
            self._state_dirty = True
            self._out = None
            return
        if name in self._alias_names:
            self._alias_vals[:, self._alias_names.index(name)] = x
        for col, f in self._columns(name):
            self._pp[:, col] = f * x
            if v.causality == "input" and self._p is not None:
                self._p[:, col] = f * x  # inputs act at once (the balance integrates their work)
        if v.causality == "parameter":
            self._initialized = False
        self._out = None

    def set(self, name: str, value, body=None) -> None:
        """Set a parameter, input or start state by name (``rotor.rate``; or ``rate`` with ``body="rotor"``), for
        every copy of the tree.

        Raises
        ------
        ConfigError
            Unknown name, a derived output, or a value that is not allowed (named with the rule).
        """
        name = TreeKernel._full(self, name, body)
        v = TreeKernel._var(self, name)
        if v.type == "String":
            self._set_integrator(value)
            return
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ConfigError(name, value, f"a real number in {v.unit or '1'}") from None
        if not math.isfinite(x):
            raise ConfigError(name, value, TreeKernel._rule(self, name, v))
        if name == "max_step":
            self._check_positive(name, x)
            self.max_step = x
        elif name == "max_drift":
            if x < 0:
                raise ConfigError(name, value, "a number >= 0 (0: the health monitor off)")
            self.max_drift = x
            self._pp[:, 1] = x
            if self._p is not None:
                self._p[:, 1] = x
        else:
            TreeKernel._assign(self, name, v, np.full(self.n_systems, x))

    def _assign_many(self, name: str, v: Variable, x: np.ndarray) -> None:
        """One value per copy of the tree (Model.set_many checked the name and the shape)."""
        TreeKernel._assign(self, name, v, x)

    def get(self, name: str, body=None, system: int = 0):
        """Value of a variable by full name (or the body's own name with ``body=``), of copy ``system``."""
        name = TreeKernel._full(self, name, body)
        v = TreeKernel._var(self, name)
        if v.type == "String":
            return self.integrator
        if v.causality == "output":
            return float(self._outputs_array()[system, self._out_index[name]])
        if name == "max_step":
            return self.max_step
        if name == "max_drift":
            return self.max_drift
        if name in self._alias_names:
            return float(self._alias_vals[system, self._alias_names.index(name)])
        col, f = self._columns(name)[0]
        return float(self._pp[system, col] / f)

    def outputs(self, body=None) -> dict[str, float]:
        """Every output by full name (``body``: only that body's, by its own names), of the first copy."""
        row = self._outputs_array()[0]
        if body is None:
            return {n: float(row[k]) for k, n in enumerate(self._out_names)}
        pre = TreeKernel._full(self, "", body)
        return {n[len(pre):]: float(row[k]) for k, n in enumerate(self._out_names) if n.startswith(pre)}

    def outputs_array(self) -> np.ndarray:
        """(n_systems, nout) outputs in the order of :func:`tree_output_names` (a copy)."""
        return self._outputs_array().copy()

    def parameters(self, body=None) -> dict:
        return {n: self.get(n) for n, v in self.variables.items() if v.causality == "parameter"}

    def inputs(self, body=None) -> dict[str, float]:
        return {n: self.get(n) for n, v in self.variables.items() if v.causality == "input"}

    # ----------------------------------------------------------------------------------------------- stepping
    def initialize(self) -> None:
        """Take the parameters and start the state (quaternions normalised, the health monitor started)."""
        p_old = self._p if not self._state_dirty else None
        if not self._initialized:
            self._p = self._pp.copy()
            self._initialized = True
            if p_old is not None:
                _engine.tree_reparam(self.layout.desc, self._y, p_old, self._p)
        if self._state_dirty:
            bad = _engine.tree_start(self.layout.desc, self._y, self._p)
            if bad >= 0:
                for b, body in enumerate(self._bodies):
                    if body.joint in ("ball", "free_rotation", "free"):
                        k = self.layout.coord_slots[(b, "q_w")]
                        q = self._y[bad, k:k + 4]
                        if not np.linalg.norm(q) > 0:
                            raise ConfigError(f"{body.name}.q", q.tolist(), "a non-zero quaternion (it is normalised)")
                raise ConfigError("state", self._y[bad, :self.layout.nx].tolist(), "finite start values")
            self._state_dirty = False
            self._out = None

    def _check_call(self, h: float, what: str) -> None:
        """Refuse at once a fixed-step call of more internal steps than one call may take (adaptive and dop853
        fail in the engine when their error control needs more)."""
        if self.integrator in _FIXED and _engine.substeps(h, self.max_step) == 0:
            self._refuse_work(h, what)

    def _step_engine(self, h: float, t: float) -> None:
        method = _METHOD_CODES[self.integrator]
        saved = (self._y.copy(), self._hint.copy())
        failed = _engine.tree_advance(self.layout.desc, method, self._y, self._p, h, self.tolerance, self.tolerance,
                                      self.max_step, self._hint, self._stats, self._status, 0)
        if failed:
            b = int(np.flatnonzero(self._status)[0])
            k = int(self._status[b])
            self._status[:] = 0
            self._y, self._hint = saved
            raise IntegrationError(TreeKernel._blowup(self, b, self._y[b], t, h, k,
                                                f"the step from t = {t!r} s with h = {h!r} s"))

    #: Tree integrators whose trajectory call runs over all its output points with its own steps and interpolates
    #: them (dense output, gs_ode_trajectory): not the bits of a loop of :meth:`step`. The others step each output
    #: interval as :meth:`step` does.
    _DENSE = ("adaptive", "dop853")

    def trajectory_is_steps(self, dt: float | None = None) -> bool:
        """Whether :meth:`trajectory` over several output intervals (of ``dt``; None: intervals no shorter than
        max_step) gives the bits of a loop of :meth:`step` with the integrator set: euler and rk4 do where max_step
        is no longer than the interval (each output interval stepped as :meth:`step` steps it; longer steps span
        the output points, which come from their continuous extension); adaptive and dop853 do not (their steps
        span the output points, which come from the dense output), nor do the implicit methods (a trajectory keeps
        their Newton matrix over the run: equal to round-off, not in every bit; steps longer than the output
        interval take the outputs from their collocation polynomial)."""
        if self.integrator in TreeKernel._DENSE or self.integrator in _IMPLICIT:
            return False
        return dt is None or float(self.max_step) <= float(dt)

    def input_names(self) -> list[str]:
        """The inputs by full name (``<body>.motor_torque``, ``<body>.tau_x``; bare in a scene of one body)."""
        return [n for n, v in self.variables.items() if v.causality == "input"]

    # ----------------------------------------------------------------------------------------------- the systems
    def n_systems(self) -> int:
        """Copies of the tree the model steps, one state row each (the sweeps' replicas)."""
        return self._n_systems

    def coordinates(self) -> list[tuple[str, str, int]]:
        """A system's continuous coordinates: (variable name, coordinate, slot in its state row), in slot order
        (a circular orbit's ``orbit_anomaly`` last)."""
        name = self.scene.var_name
        slots = sorted((k, c if b is None else name(self._bodies[b].name, c), c)
                       for (b, c), k in self.layout.coord_slots.items())
        return [(v, c, k) for k, v, c in slots]

    def n_coords(self) -> int:
        return self.layout.nx

    def _restart_rows(self, rows: np.ndarray, coords: np.ndarray) -> int:
        y = self._y[rows].copy()
        y[:, :coords.shape[1]] = coords
        bad = _engine.tree_start(self.layout.desc, y, np.ascontiguousarray(self._p[rows]))
        if bad < 0:
            self._y[rows] = y
            self._out = None
        return bad

    def fastest_rate(self, system: int = 0) -> float:
        return float(_engine.tree_scalar(self.layout.desc, self._y[system:system + 1], self._p[system:system + 1],
                                         1))

    def _held_derivatives(self, y: np.ndarray, p: np.ndarray) -> np.ndarray:
        """The state's derivative with the joints that rest on an impact stop held there: a joint on its stop with
        rate 0 whose free acceleration points into it is kept at rest by the stop's reaction, a generalized force
        lambda_j on its coordinate (the impacts' contact as a constraint: sum_r A_jr lambda_r = -a_j, A's columns the
        derivative's response to a unit force at each held joint, the engine's being linear in it). A joint whose
        reaction would pull is not held (it lifts off), and the rest are solved again."""
        desc, nx = self.layout.desc, self.layout.nx
        dy0 = np.zeros(nx + 1)
        _engine.tree_derivatives(desc, y, p, dy0)
        held = []
        for b, body in enumerate(self._bodies):
            if body.stop != "impact" or body.joint not in ("hinge", "slider"):
                continue
            k = self.layout.coord_slots[(b, "angle" if body.joint == "hinge" else "displacement")]
            x, v, a = y[k], y[k + 1], dy0[k + 1]
            lo = body.lower is not None and x <= TreeKernel._pp_value(self, p, b, _engine.TB_LO) and a < 0.0
            hi = body.upper is not None and x >= TreeKernel._pp_value(self, p, b, _engine.TB_HI) and a > 0.0
            if v == 0.0 and (lo or hi):
                held.append((b, k))
        while held:
            cols = []
            for b, _ in held:   # the derivative's response to a unit generalized force at joint b
                q = p.copy()
                q[self.layout.body_offset(b) + _engine.TB_MOTOR] += 1.0
                d = np.zeros(nx + 1)
                _engine.tree_derivatives(desc, y, q, d)
                cols.append(d - dy0)
            A = np.array([[c[k + 1] for c in cols] for _, k in held])
            lam = np.linalg.solve(A, -np.array([dy0[k + 1] for _, k in held]))
            pushes = [(lam[r] > 0.0) == (dy0[k + 1] < 0.0) for r, (_, k) in enumerate(held)]
            if all(pushes):
                return dy0 + sum(lr * c for lr, c in zip(lam, cols))
            held = [h for h, ok in zip(held, pushes) if ok]
        return dy0

    def _pp_value(self, p: np.ndarray, b: int, col: int) -> float:
        return float(p[self.layout.body_offset(b) + col])

    def specific_force(self, system: int = 0) -> np.ndarray:
        """(n_bodies, 3) specific force at every body's origin, body frames (Model.specific_force)."""
        out = self._outputs_array()[system]   # initialises
        y, p = self._y[system], self._p[system]
        nx, nb = self.layout.nx, len(BODY_OUTPUTS)
        dy = TreeKernel._held_derivatives(self, y, p)
        ddy, dout = np.zeros(nx + 1), np.zeros(self.layout.nout)
        _engine.tree_directional(self.layout.desc, y, p, dy[:nx].copy(), np.zeros_like(p), ddy, dout)
        g = float(p[_engine.TP_G]) * p[_engine.TP_GDIR:_engine.TP_GDIR + 3]
        from .core.rotations import quat_to_matrix

        qw, vw = BODY_OUTPUTS.index("q_world_w"), BODY_OUTPUTS.index("v_world_x")
        at = nx + nb * np.arange(self.n_bodies)
        R = quat_to_matrix(np.stack([out[k + qw:k + qw + 4] for k in at]))   # body -> world, (n_bodies, 3, 3)
        a = np.stack([dout[k + vw:k + vw + 3] for k in at])
        return np.einsum("bji,bj->bi", R, a - g)   # R^T (a - g)

    def on_face(self, system: int = 0) -> list[str]:
        """The rigid contacts lying flat on a face (Model.on_face): their outputs' stems, from the modes in the
        state (gyrosim_tree.h GS_CM_FLAT, after the health monitor: the state row's last slots)."""
        self._outputs_array()   # initialises
        contacts = contacts_of(self.scene)
        if not any(pl.model == "rigid" for pl in getattr(self.scene, "planes", ())):
            return []
        ym = self.layout.ny - _engine.CM_NP * len(contacts)
        y = self._y[system]
        return [self.scene.var_name(self._bodies[h.body].name, stem) for c, (h, _, stem) in enumerate(contacts)
                if y[ym + _engine.CM_NP * c + _engine.CM_FLAT] != 0.0]

    def dynamics_kernel(self, system: int = 0) -> str:
        p = self._p if self._p is not None else self._pp   # before initialize: the parameters set so far
        return TREE_KERNELS[int(_engine.tree_scalar(self.layout.desc, self._y[system:system + 1],
                                                    p[system:system + 1], 2)) & 7]

    def _forget(self) -> None:
        """A new integrator: no step-size history."""
        self._hint[:] = 0.0

    def drift_measure(self, out0: np.ndarray) -> tuple:
        """What the sweeps measure of each copy's drift from its outputs at the start ``out0``: the health
        monitor's own scales (the energy scale S0 and the tree's momentum scale), ``drifts(traj) ->
        (|energy_error|, |L - L0|)`` over a trajectory's rows (the change of the vector L, conserved where the tree
        is torque-free), and the trajectory's options (none)."""
        col = self._out_index
        Lc = [col["L_x"], col["L_y"], col["L_z"]]
        L0 = out0[:, Lc]
        e_col, mon = col["energy_error"], self.layout.nx

        def drifts(traj):
            e = np.fmax.reduce(np.abs(traj[1:, :, e_col]), axis=0)
            return e, np.fmax.reduce(np.sqrt(np.sum((traj[1:, :, Lc] - L0) ** 2, axis=2)), axis=0)

        return self._y[:, mon + _MON_ESCALE].copy(), self._y[:, mon + _MON_LSCALE].copy(), drifts, {}

    def inert_bodies(self, system: int = 0) -> list:
        """The bodies that carry no inertia at their joint (the parameters of copy ``system`` as set; a fixed joint
        has no coordinate and is never one): neither mass nor inertia, or a hinge body whose mass sits on its axis
        with no moment about it. Those with nothing below them first (their joint then carries nothing at all: the
        equations of motion are singular everywhere), then the others (singular where the bodies below line up with
        the joint).

        Returns
        -------
        list of (parameter, value, what it is, alone, advice)
            The parameter to name (``lower.mass``; ``lower.cm_z`` for a mass on the axis) and its value, a
            sentence saying what is wrong, whether nothing below carries inertia, and what to do.
        """
        sc, tree = self.scene, self.scene.tree

        def get(b, n):
            return self.get(sc.var_name(b.name, n), system=system)

        below = {i: [] for i in range(len(tree))}
        for i, b in enumerate(tree):
            j = b.parent
            while j >= 0:
                below[j].append(i)
                j = tree[j].parent
        import dataclasses

        from .scene_tree import inert_joints

        def now(b):   # the body with its values as set
            J = np.asarray(b.inertia, dtype=float).copy()
            J[np.diag_indices(3)] = [get(b, n) for n in ("I1", "I2", "I3")]
            return dataclasses.replace(b, mass=get(b, "mass"), inertia=J,
                                       cm=np.array([get(b, f"cm_{c}") for c in "xyz"]))

        bodies = [now(b) for b in tree]
        # the joints that carry nothing in any configuration: the scene file's rule (scene_tree.inert_joints)
        out = []
        for i, n, v, what, advice in inert_joints(bodies):
            if n.startswith("cm_"):   # a mass on the axis: name the component the scene had off it (what was set)
                axis = np.asarray(tree[i].axis, dtype=float)
                off = [c for k, c in enumerate("xyz") if abs(axis[k]) < 1.0 and float(tree[i].cm[k]) != 0.0]
                n, v = (f"cm_{off[0]}", get(tree[i], f"cm_{off[0]}")) if off else (n, v)
            out.append((sc.var_name(tree[i].name, n), v, what, True, advice))
        named = {e[0] for e in out}
        massless = {i for i, b in enumerate(bodies) if b.mass == 0.0 and not np.diag(b.inertia).any()}
        for i, b in enumerate(bodies):   # and those singular where the bodies below them line up with the joint
            if b.joint == "fixed" or all(c in massless for c in below[i]):
                continue
            if i in massless and sc.var_name(b.name, "mass") not in named:
                out.append((sc.var_name(b.name, "mass"), 0.0, f"body {b.name!r} has neither mass nor inertia "
                            "(mass and I1, I2, I3 all 0)", False, "give it mass or inertia"))
            elif b.joint == "hinge":
                axis, cm, m = np.asarray(b.axis, dtype=float), b.cm, b.mass
                if float(axis @ b.inertia @ axis) + m * float(cm @ cm - (cm @ axis) ** 2) == 0.0:
                    across = [c for k, c in enumerate("xyz") if abs(axis[k]) < 1.0]
                    pick = next((c for c in across if float(tree[i].cm["xyz".index(c)]) != 0.0), across[0])
                    out.append((sc.var_name(b.name, f"cm_{pick}"), float(cm["xyz".index(pick)]),
                                f"body {b.name!r} has no moment of inertia about its hinge axis (its mass {m:g} kg "
                                f"on the axis, cm = [{', '.join(f'{x:g}' for x in cm)}] m, and no moment of its own "
                                "about it)", False,
                                "move its centre of mass off the axis or give it a moment of inertia about it"))
        return sorted(out, key=lambda e: not e[3])

    def gimbal_lock(self, y=None, system: int = 0) -> str | None:
        """A message naming gimbal lock when two hinge axes of a chain are within 0.1 rad of lining up at the state
        ``y`` (default: now) of copy ``system``, else None."""
        if not self._initialized or self._state_dirty:
            self.initialize()
        y = self._y[system] if y is None else y
        hinges = [i for i, b in enumerate(self._bodies) if b.joint == "hinge"]
        from .core.rotations import quat_to_matrix

        out = np.empty(self.layout.nout)
        _engine.tree_outputs(self.layout.desc, y.reshape(1, -1), self._p[system], out)
        at = self.layout.nx + len(BODY_OUTPUTS) * np.arange(self.n_bodies) + BODY_OUTPUTS.index("q_world_w")
        qw = {i: out[at[i]:at[i] + 4] for i in range(self.n_bodies)}

        def axis_world(i):
            b = self._bodies[i]
            R = np.eye(3) if b.parent < 0 else quat_to_matrix(qw[b.parent])
            return R @ np.asarray(b.axis)

        def parallel(a, b):
            return abs(float(np.dot(axis_world(a), axis_world(b)))) > math.cos(0.1)

        for i in hinges:
            j = self._bodies[i].parent
            between = []   # the hinges between j and i: a lock needs one across the two lined-up axes (a gimbal)
            while j >= 0 and self._bodies[j].joint == "hinge":
                # axes parallel with every hinge between them parallel too (a planar chain) are so by design
                if parallel(i, j) and any(not parallel(k, i) for k in between):
                    ang = math.acos(min(1.0, abs(float(np.dot(axis_world(i), axis_world(j))))))
                    return (f"gimbal lock: the axes of {self._bodies[j].name!r} and {self._bodies[i].name!r} are "
                            f"{ang:.3g} rad from lining up, where the gimbals between them carry too little inertia "
                            "about the lost axis (massless gimbals make the motion singular there); give the gimbals "
                            "inertia, or keep the inner angle away from 0")
                between.append(j)
                j = self._bodies[j].parent
        return None

    def _stiffest_rate(self, y0: np.ndarray, p: np.ndarray) -> float:
        """The largest |eigenvalue| (1/s) of the equations' Jacobian at the state ``y0`` (complex step, one column
        per state; 0 beyond 200 states or where it is not finite): the rate an explicit step must resolve, springs,
        dampers and contacts included, where the fastest rate of the motion (tree_scalar) sees only the spins."""
        nx = self.layout.nx
        if nx > 200:
            return 0.0
        y = np.ascontiguousarray(y0.reshape(1, -1))
        pp = np.ascontiguousarray(p.reshape(1, -1))
        A = np.zeros((nx, nx))
        ddy, dout, vp = np.zeros(nx + 1), np.zeros(self.layout.nout), np.zeros(pp.shape[1])
        for j in range(nx):
            vy = np.zeros(nx)
            vy[j] = 1.0
            _engine.tree_directional(self.layout.desc, y, pp, vy, vp, ddy, dout)
            A[:, j] = ddy[:nx]
        if not np.all(np.isfinite(A)):
            return 0.0
        return float(np.max(np.abs(np.linalg.eigvals(A)), initial=0.0))

    def _blowup(self, b: int, y0: np.ndarray, t: float, h: float, k: int, where: str) -> str:
        """The message for copy ``b`` failing from state ``y0``: what drifted (the interval again with the monitor
        off), gimbal lock where the axes line up, and advice."""
        pb = self._p[b:b + 1]
        if self.integrator in ("splitting", "splitting4") and not int(
                _engine.tree_scalar(self.layout.desc, y0.reshape(1, -1), pb, 2)) & 8:
            from .scene_tree import split_refusal

            return (f"integrator {self.integrator!r} cannot step {where}: the parameters set since the start leave the "
                    f"gyrostat's shape; use {split_refusal()}")
        lock = TreeKernel.gimbal_lock(self, y0, b)
        rate = float(_engine.tree_scalar(self.layout.desc, y0.reshape(1, -1), pb, 1))
        stiff = (TreeKernel._stiffest_rate(self, y0, pb[0]) if self.integrator in _FIXED
                 and self.integrator not in _IMPLICIT else 0.0)
        n_sub = _engine.substeps(h, self.max_step) if self.integrator in _FIXED else 0
        at = f" at internal step {k} of {n_sub}" if n_sub > 1 else ""
        y = y0.reshape(1, -1).copy()
        p = pb.copy()
        p[:, 1] = 0.0
        hint, stats, st = self._hint[b:b + 1].copy(), np.zeros((1, 3), dtype=np.int64), np.zeros(1, dtype=np.int32)
        fails = _engine.tree_advance(self.layout.desc, _METHOD_CODES[self.integrator], y, p, h, self.tolerance,
                                     self.tolerance, self.max_step, hint, stats, st, 1)
        if fails and self.integrator in _IMPLICIT:
            cause = f"the implicit step's Newton iterations did not converge, or the state became non-finite{at}"
        elif fails:
            cause = f"the state became non-finite or overflowed{at}"
        else:
            d = np.empty((1, 2))
            _engine.tree_drift(self.layout.desc, y, pb, d)
            i = int(np.argmax(d[0]))
            cause = (f"{('the energy balance', 'the angular momentum')[i]} drifted by {d[0, i]:.3g} of its scale{at} "
                     f"(max_drift = {self.max_drift:g}, the health monitor's bound)")
        inert = [e for e in self.inert_bodies(b) if e[3]]
        if inert:  # a joint that carries nothing: singular everywhere (not the configuration, not the step)
            name, value, what, _, todo = inert[0]
            advice = (f"{what}, so nothing resists its joint's acceleration and the equations of motion are singular "
                      f"({name} = {value:g}); {todo}")
        elif lock:
            advice = lock
        elif self.integrator in ("adaptive", "dop853"):
            advice = "tighten or loosen the tolerance, check the parameters, or try the integrator 'rk4'"
        elif self.integrator in _IMPLICIT and rate > 0:
            hi = h / n_sub if n_sub > 0 else h
            advice = (f"the fastest rate in the state is {rate:.4g} rad/s (h*rate = {hi * rate:.3g}); use a smaller "
                      "max_step, or the integrator 'dop853'")
        elif rate > 0 or stiff > 0:
            hi = h / n_sub if n_sub > 0 else h
            spins_allow = rate == 0 or 0.5 / rate > hi   # the step resolves the fastest spin
            if stiff > rate and spins_allow:   # a stiff force (a spring, a damper, a contact) sets the limit
                advice = (f"the step {hi:.3g} s is within the fastest rate in the state ({rate:.4g} rad/s), but the "
                          f"equations there have a rate of {stiff:.4g} 1/s (the largest eigenvalue of their "
                          "Jacobian: a stiff spring, damper or contact); use max_step <= "
                          f"{2.0 / stiff:.3g} s, the integrator 'midpoint' (A-stable: it steps over stiff forces) or "
                          "'dop853'")
            else:
                advice = (f"the fastest rate in the state is {rate:.4g} rad/s; use max_step <= {0.5 / rate:.3g} s, "
                          "the integrator 'midpoint' (A-stable: it steps over fast spin and nutation) or 'dop853'")
        else:
            advice = "check the parameters, or try the integrator 'dop853'"
        return f"integrator {self.integrator!r} blew up in {where}: {cause}; {advice}"

    def trajectory(self, dt: float, n: int, *, angles: bool = True, momentum: bool = True,
                   status: np.ndarray | None = None) -> np.ndarray:
        """Advance ``n`` output intervals of ``dt`` s in one engine call. euler and rk4 give the bits of ``n`` calls
        of :meth:`step`; adaptive and dop853 take the steps their error control chooses over the whole call (1001
        output points do not force 1001 steps) and evaluate the output points with their dense output (4th and 7th
        order; quaternions back to unit norm, the health monitor at every point): the step loop's values to the
        tolerance's order, not its bits (one interval: its bits).

        ``status``: an (n_systems,) int32 array to keep going when copies blow up (sweeps): a failing copy gets the
        output interval (1-based) in which it failed and NaN rows from there; the others run to the end.

        Returns
        -------
        (n + 1, n_systems, nout) ndarray
            The outputs (:func:`tree_output_names`) at ``time + k*dt``, ``k = 0..n``.
        """
        del angles, momentum  # every output of a tree is computed
        keep_going = status is not None
        dt, n, t = self._start_run(dt, n, status, self.n_systems)
        out = np.empty((n + 1, self.n_systems, self.layout.nout))
        st = status if keep_going else np.zeros(self.n_systems, dtype=np.int32)
        saved = (self._y.copy(), self._hint.copy())
        failed = _engine.tree_trajectory(self.layout.desc, _METHOD_CODES[self.integrator], self._y, self._p, dt, n,
                                         self.tolerance, self.tolerance, self.max_step, self._hint, self._stats, st,
                                         0, out)
        if failed and not keep_going:
            b = int(np.flatnonzero(st)[0])
            k = int(st[b])
            t_k = t + (k - 1) * dt
            msg = TreeKernel._blowup(self, b, self._y[b], t_k, dt, 1, f"the output interval from t = {t_k!r} s to "
                               f"{t + k * dt!r} s (interval {k} of {n})")
            self._y, self._hint = saved
            err = IntegrationError(msg)
            err.rows = out[:k]
            raise err
        self._tick(t, dt, n)
        return out

    def _outputs_array(self) -> np.ndarray:
        if self._out is None:
            if not self._initialized or self._state_dirty:
                self.initialize()
            out = np.empty((self.n_systems, self.layout.nout))
            _engine.tree_outputs(self.layout.desc, self._y, self._p, out)
            self._out = out
        return self._out

    # ----------------------------------------------------------------------------------------------- state
    _STATE_FIELDS = ("_pp", "_alias_vals", "_y", "_hint", "_stats", "_p",
                     "integrator", "max_step", "max_drift", "tolerance", "start_time", "stop_time", "_t_base", "_n",
                     "_h", "_initialized", "_state_dirty")

    def _restored(self) -> None:
        """After set_state: the restored fields are the whole state (the parameter rows included)."""
