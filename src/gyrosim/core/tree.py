"""Trees of rigid bodies: the Python face of the engine's tree (``core/engine/gyrosim_tree.h``).

A :class:`TreeBody` describes one body and its joint to its parent (docs/trees.md); :class:`TreeLayout`
turns a tuple of them (topological order: a parent before its children) and the coupling springs into the arrays
the engine takes: the description (int32), one system's parameter row and start state, and the names of the state
and output columns.

Units (SI): kg, m, s, rad, N*m. Frames: a body's frame has its origin at its joint point; world z up, gravity
along -z. Quaternions (w, x, y, z), scalar first, rotating child-frame vectors into the parent frame.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import _engine

__all__ = ["TreeBody", "TreeLayout", "Orbit", "Spring", "Force", "Shape", "Plane", "JOINTS", "JOINT_COORDS",
           "MU_EARTH", "BODY_SLOTS", "GRAVITY_DOWN"]

#: The joints and their engine codes (free_rotation is a ball whose joint point is the centre of mass).
JOINTS = {"free_rotation": _engine.J_BALL, "ball": _engine.J_BALL, "hinge": _engine.J_HINGE,
          "free": _engine.J_FREE, "fixed": _engine.J_FIXED, "slider": _engine.J_SLIDER}

#: Gravity's default direction (world): along -z.
GRAVITY_DOWN = (0.0, 0.0, -1.0)

#: A body's parameters and inputs by short name: their slot in the body's block of a parameter row
#: (``gyrosim_tree.h`` GS_TB_*). A hinge's and a slider's spring, damping and motor share slots (their units differ).
BODY_SLOTS = {"mass": _engine.TB_MASS, "I1": _engine.TB_I, "I2": _engine.TB_I + 1, "I3": _engine.TB_I + 2,
              "cm_x": _engine.TB_CM, "cm_y": _engine.TB_CM + 1, "cm_z": _engine.TB_CM + 2,
              "pos_x": _engine.TB_POS, "pos_y": _engine.TB_POS + 1, "pos_z": _engine.TB_POS + 2,
              "stiffness": _engine.TB_STIFF, "rest_angle": _engine.TB_REST, "rest_displacement": _engine.TB_REST,
              "joint_damping": _engine.TB_DAMP, "damping": _engine.TB_DAMP,
              "stiffness_x": _engine.TB_KB, "stiffness_y": _engine.TB_KB + 1, "stiffness_z": _engine.TB_KB + 2,
              "joint_damping_x": _engine.TB_CB, "joint_damping_y": _engine.TB_CB + 1,
              "joint_damping_z": _engine.TB_CB + 2,
              "lower": _engine.TB_LO, "upper": _engine.TB_HI, "stop_stiffness": _engine.TB_STOP_K,
              "stop_damping": _engine.TB_STOP_C, "restitution": _engine.TB_RESTITUTION}
#: A body's inputs by short name: their slot in its block.
INPUT_SLOTS = {"motor_torque": _engine.TB_MOTOR, "motor_force": _engine.TB_MOTOR, "tau_x": _engine.TB_TAU,
               "tau_y": _engine.TB_TAU + 1, "tau_z": _engine.TB_TAU + 2}

#: The state variables of each joint, in the engine's order.
JOINT_COORDS = {
    "free_rotation": ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"),
    "ball": ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"),
    "hinge": ("angle", "rate"),
    "free": ("q_w", "q_x", "q_y", "q_z", "r_x", "r_y", "r_z", "omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"),
    "fixed": (),
    "slider": ("displacement", "velocity"),
}

#: The outputs every body has besides its joint's state, and the scene-wide outputs.
BODY_OUTPUTS = ("q_world_w", "q_world_x", "q_world_y", "q_world_z", "r_world_x", "r_world_y", "r_world_z",
                "v_world_x", "v_world_y", "v_world_z")
SCENE_OUTPUTS = ("energy", "energy_error", "L_x", "L_y", "L_z")
#: Every contact's outputs (a shape against a plane), in the engine's order (gyrosim_tree.h GS_CT_*).
CONTACT_OUTPUTS = ("gap", "normal_force", "friction_x", "friction_y", "friction_z", "slip_speed", "contact_x",
                   "contact_y", "contact_z", "mode", "jellett")
#: Every closed loop's outputs and every gear's (gyrosim_tree.h GS_LO_*, GS_GO_*), scene-wide ``<name>.<output>``.
LOOP_OUTPUTS = ("residual", "rate_residual", "f_x", "f_y", "f_z")
GEAR_OUTPUTS = ("torque",)
LOOP_KINDS = {"spherical": _engine.LOOP_SPHERICAL, "revolute": _engine.LOOP_REVOLUTE,
              "prismatic": _engine.LOOP_PRISMATIC}
#: The contact modes (the ``mode`` output's values).
CONTACT_MODES = ("apart", "sliding", "rolling", "resting")
#: Shape kinds and their engine codes; the normal and friction laws and theirs.
SHAPE_KINDS = {"sphere": _engine.SHAPE_SPHERE, "ellipsoid": _engine.SHAPE_ELLIPSOID, "disk": _engine.SHAPE_DISK,
               "cylinder": _engine.SHAPE_CYLINDER, "point": _engine.SHAPE_POINT}
CONTACT_MODELS = {"rigid": _engine.CONTACT_RIGID, "compliant": _engine.CONTACT_COMPLIANT}
FRICTION_MODELS = {"coulomb": _engine.FRICTION_COULOMB, "regularized": _engine.FRICTION_REGULARIZED}
#: A plane's parameters by name: their slot in its block of a parameter row (GS_PLN_*).
PLANE_SLOTS = {"friction": _engine.PLN_MU, "restitution": _engine.PLN_E, "spin_radius": _engine.PLN_RS,
               "rolling_resistance": _engine.PLN_RR, "stiffness": _engine.PLN_K, "damping": _engine.PLN_C,
               "slip_velocity": _engine.PLN_VS}
#: On an orbit: the circular orbit's anomaly (a coordinate of the state, after the joints'), every body's attitude
#: in the orbit frame, the orbit point's position and velocity (scene-wide, from the central body).
ORBIT_COORD = "orbit_anomaly"
ORBIT_BODY_OUTPUTS = ("q_orbit_w", "q_orbit_x", "q_orbit_y", "q_orbit_z")
ORBIT_OUTPUTS = ("orbit_r_x", "orbit_r_y", "orbit_r_z", "orbit_v_x", "orbit_v_y", "orbit_v_z")
#: The gravitational parameter of the Earth (m^3/s^2), the default central body.
MU_EARTH = 3.986004418e14


@dataclass(frozen=True)
class Orbit:
    """A tree's orbit about a central body (``[scene.orbit]``; see ``gyrosim_tree.h``).

    Attributes
    ----------
    mu : float
        The central body's gravitational parameter, m^3/s^2.
    radius : float or None
        m: a circular orbit of the tree's reference point (the world origin) in the world x-y plane, starting at
        ``radius * (cos anomaly, sin anomaly, 0)``, moving towards +y at anomaly 0 (orbit normal +z). None: every
        root is ``free`` and moves under the central force from its own ``r``, ``v`` (the world origin is the
        central body's centre).
    anomaly : float
        rad, the circular orbit's start anomaly.
    """

    mu: float = MU_EARTH
    radius: float | None = None
    anomaly: float = 0.0

    @property
    def circular(self) -> bool:
        return self.radius is not None

    @property
    def code(self) -> int:
        return _engine.ORBIT_CIRCULAR if self.circular else _engine.ORBIT_KEPLER

    @property
    def rate(self) -> float:
        """The circular orbit's mean motion n = sqrt(mu / radius^3), rad/s."""
        return float(np.sqrt(self.mu / self.radius ** 3))


def _vec(x, n=3):
    return np.array(x, dtype=float).reshape(n)


def _child_axis(q: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """A joint's axis in the child's frame at the joint's zero: Q^T axis (the engine's GS_TB_AXIS), for the axis in
    the parent's frame and the placement Q; the axis itself where Q is the identity (bit for bit)."""
    if q[0] == 1.0 and not q[1:].any():
        return axis
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R.T @ axis


@dataclass(frozen=True)
class TreeBody:
    """One body of a tree and its joint to its parent.

    Attributes
    ----------
    name : str
    parent : int
        Index of the parent body in the tree (it comes before this one), -1 for the world.
    joint : {"free_rotation", "ball", "hinge", "free", "fixed"}
    pos : (3,) ndarray
        The joint point in the parent's frame (the world for a root), m; the origin of this body's frame.
    axis : (3,) ndarray
        Unit hinge axis in the parent frame (equal in this body's frame).
    mass : float
        kg.
    cm : (3,) ndarray
        Centre of mass in the body frame, from the joint point, m.
    inertia : (3, 3) ndarray
        Inertia about the centre of mass in the body frame (matrix elements), kg*m^2.
    stiffness, rest_angle, damping : float
        Hinge spring (N*m/rad, rad) and the joint's viscous damping (hinge N*m*s/rad; ball and free N*m*s).
    motor_input, torque_input : bool
        A hinge motor-torque input ``motor_torque``; an external body-frame torque input ``tau_x..z``.
    q0, omega0, angle0, rate0, r0, v0
        Start state of the joint (only those of its kind are used; a slider's displacement and velocity are
        angle0, rate0).
    rotation : (4,) ndarray
        The joint's placement: the child's frame at the joint's zero in the parent's (unit quaternion w, x, y, z).
    ball_stiffness, ball_damping : (3,) ndarray
        A ball's spring about its zero (N*m/rad per body axis; the torque of 1/2 phi^T K phi) and its damping per
        body axis (N*m*s/rad), besides ``damping``.
    lower, upper : float or None
        A hinge's or slider's stops (rad, m); ``stop_stiffness`` and ``stop_damping`` the spring-damper that acts
        beyond them, or with ``stop = "impact"`` an impact with the coefficient of ``restitution`` (events).
    """

    name: str
    parent: int = -1
    joint: str = "free_rotation"
    pos: np.ndarray = field(default_factory=lambda: np.zeros(3))
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    mass: float = 0.0
    cm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.eye(3))
    stiffness: float = 0.0
    rest_angle: float = 0.0
    damping: float = 0.0
    motor_input: bool = False
    motor0: float = 0.0
    torque_input: bool = False
    q0: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    omega0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    angle0: float = 0.0
    rate0: float = 0.0
    r0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    v0: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))
    ball_stiffness: np.ndarray = field(default_factory=lambda: np.zeros(3))
    ball_damping: np.ndarray = field(default_factory=lambda: np.zeros(3))
    lower: float | None = None
    upper: float | None = None
    stop_stiffness: float | None = None   # None: the default the scene loader sets (scene_tree.stop_defaults)
    stop_damping: float | None = None
    stop: str = "spring"
    restitution: float = 1.0

    @property
    def coords(self) -> tuple[str, ...]:
        """The joint's state variables, in the engine's order."""
        return JOINT_COORDS[self.joint]

    def principal(self) -> np.ndarray:
        """(3,) the diagonal of the inertia (I1, I2, I3 when the body axes are principal), kg*m^2."""
        return np.diag(self.inertia).copy()


@dataclass(frozen=True)
class Spring:
    """A linear spring-damper between a point of body ``a`` and a point of body ``b`` (-1: the world); points in the
    body frames (the world's for -1), m; ``stiffness`` N/m, ``rest_length`` m, ``damping`` N*s/m."""

    name: str
    a: int
    point_a: np.ndarray
    b: int
    point_b: np.ndarray
    stiffness: float = 0.0
    rest_length: float = 0.0
    damping: float = 0.0


@dataclass(frozen=True)
class Force:
    """A force input (N) at ``point`` of body ``body`` (its frame, m), given in the body's frame or the world's."""

    name: str
    body: int
    point: np.ndarray
    world: bool = False


@dataclass(frozen=True)
class Shape:
    """A convex shape on body ``body`` for contact with the planes: ``kind`` (SHAPE_KINDS), its centre ``center``
    (m, body frame), its frame's axes in the body frame ``axes`` (3x3, columns; a disk's or cylinder's axis is the
    third) and its dimensions ``dims`` (m: sphere, disk (radius, 0, 0); ellipsoid the semi-axes; cylinder (radius,
    length, 0); point none)."""

    name: str
    body: int
    kind: str
    center: np.ndarray
    axes: np.ndarray
    dims: tuple = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Plane:
    """A plane fixed in the world through ``point`` (m) with unit ``normal``, and its contact law: ``model``
    (CONTACT_MODELS), ``friction_model`` (FRICTION_MODELS) and the parameters of PLANE_SLOTS."""

    name: str
    point: np.ndarray
    normal: np.ndarray
    model: str = "compliant"
    friction_model: str = "regularized"
    friction: float = 0.0
    restitution: float = 0.0
    spin_radius: float = 0.0
    rolling_resistance: float = 0.0
    stiffness: float = 0.0
    damping: float = 0.0
    slip_velocity: float = 0.0


@dataclass(frozen=True)
class Loop:
    """A closed loop (DESIGN 4b ``[[loop]]``): body ``b``'s point ``point_b`` (its frame) held on body ``a``'s
    ``point_a`` (``a`` = -1: the world, the point in world coordinates); ``kind`` (LOOP_KINDS): spherical (the points
    coincide), revolute (and the unit axes ``axis_a``, ``axis_b`` in their bodies' frames stay aligned) or prismatic
    (b's point stays on a's axis through a's point, and the bodies' relative rotation stays ``q0``, R_a^T R_b as a
    quaternion w, x, y, z)."""

    name: str
    a: int
    b: int
    kind: str
    point_a: np.ndarray
    point_b: np.ndarray
    axis_a: np.ndarray = (0.0, 0.0, 1.0)
    axis_b: np.ndarray = (0.0, 0.0, 1.0)
    q0: np.ndarray = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class Gear:
    """A gear (DESIGN 4b ``[[gear]]``): the rate of body ``a``'s joint = ``ratio`` x the rate of body ``b``'s (hinges
    or sliders)."""

    name: str
    a: int
    b: int
    ratio: float


class TreeLayout:
    """The engine's arrays for a tree: description, parameter row, start state and column names.

    Parameters
    ----------
    bodies : sequence of TreeBody
        In topological order.
    couplings : sequence of (int, int, float)
        Torsion springs between two hinge bodies (a, b, stiffness N*m/rad): torque -k (angle_a - angle_b) on a and
        the opposite on b.
    orbit : Orbit or None
        The orbit the tree is on (the description's element after the couplings; a circular orbit's anomaly is the
        state's last coordinate, ``coord_slots[(None, "orbit_anomaly")]``).
    springs, forces : sequence of Spring, Force
        The elements (the description's tail).
    gravity_dir : (3,) sequence
        Gravity's direction (unit, world).

    Attributes
    ----------
    desc : (2 + 2n + 2c,) int32 ndarray
    nx, ny, np, nout : int
        Joint coordinates, state length, parameter length and output row length of one system.
    coord_slots : dict
        ``(body index, variable) -> column`` of the joint coordinates in the state (and the output row).
    output_names : list of (int or None, str)
        ``(body index, name)`` of every output column (``None`` for the scene-wide outputs).
    """

    def __init__(self, bodies, couplings=(), orbit: Orbit | None = None, springs=(), forces=(),
                 gravity_dir=GRAVITY_DOWN, shapes=(), planes=(), loops=(), gears=()):
        self.bodies = tuple(bodies)
        self.couplings = tuple((int(a), int(b), float(k)) for a, b, k in couplings)
        self.orbit = orbit
        self.springs, self.forces = tuple(springs), tuple(forces)
        self.shapes, self.planes = tuple(shapes), tuple(planes)
        self.loops, self.gears = tuple(loops), tuple(gears)
        closed = bool(self.loops) or bool(self.gears)
        contacts = bool(self.shapes) and bool(self.planes) or closed
        self.gravity_dir = _vec(gravity_dir)
        d = [len(self.bodies), len(self.couplings)]
        for b in self.bodies:
            d += [b.parent, JOINTS[b.joint]]
        for a, b, _ in self.couplings:
            d += [a, b]
        if orbit is not None or self.springs or self.forces or contacts:
            d.append(orbit.code if orbit is not None else _engine.ORBIT_NONE)
        if self.springs or self.forces or contacts:
            d += [len(self.springs), len(self.forces)]
            for s in self.springs:
                d += [s.a, s.b]
            for f in self.forces:
                d += [f.body, int(f.world)]
        if contacts:
            d += [len(self.shapes), len(self.planes)]
            for h in self.shapes:
                d += [h.body, SHAPE_KINDS[h.kind]]
            for pl in self.planes:
                d += [CONTACT_MODELS[pl.model], FRICTION_MODELS[pl.friction_model]]
        if closed:
            d += [len(self.loops), len(self.gears)]
            for lp in self.loops:
                d += [lp.a, lp.b, LOOP_KINDS[lp.kind]]
            for gr in self.gears:
                d += [gr.a, gr.b]
        self.desc = np.array(d, dtype=np.int32)
        self.nx, self.ny, self.np, self.nout = _engine.tree_info(self.desc)
        self.coord_slots = {}
        self.output_names = []
        at = 0
        for i, b in enumerate(self.bodies):
            for c in b.coords:
                self.coord_slots[(i, c)] = at
                self.output_names.append((i, c))
                at += 1
        if orbit is not None and orbit.circular:
            self.coord_slots[(None, ORBIT_COORD)] = at
            self.output_names.append((None, ORBIT_COORD))
        for i, _ in enumerate(self.bodies):
            for c in BODY_OUTPUTS:
                self.output_names.append((i, c))
        for c in SCENE_OUTPUTS:
            self.output_names.append((None, c))
        if orbit is not None:
            for i, _ in enumerate(self.bodies):
                for c in ORBIT_BODY_OUTPUTS:
                    self.output_names.append((i, c))
            for c in ORBIT_OUTPUTS:
                self.output_names.append((None, c))
        if contacts:
            for h in self.shapes:
                for pl in self.planes:
                    stem = h.name if len(self.planes) == 1 else f"{h.name}.{pl.name}"
                    self.output_names += [(h.body, f"{stem}.{c}") for c in CONTACT_OUTPUTS]
        for lp in self.loops:
            self.output_names += [(None, f"{lp.name}.{c}") for c in LOOP_OUTPUTS]
        for gr in self.gears:
            self.output_names += [(None, f"{gr.name}.{c}") for c in GEAR_OUTPUTS]
        assert len(self.output_names) == self.nout
        self.dof = sum({"hinge": 1, "slider": 1, "free": 6, "fixed": 0}.get(b.joint, 3) for b in self.bodies)

    def body_offset(self, i: int) -> int:
        """Where body ``i``'s parameters start in a parameter row."""
        return _engine.TP_HEAD + _engine.TB_NP * i

    def spring_offset(self, e: int) -> int:
        """Where spring element ``e``'s parameters start in a parameter row."""
        return self.body_offset(len(self.bodies)) + len(self.couplings) + _engine.SPR_NP * e

    def force_offset(self, e: int) -> int:
        """Where force element ``e``'s parameters start in a parameter row."""
        return self.spring_offset(len(self.springs)) + _engine.FRC_NP * e

    def shape_offset(self, e: int) -> int:
        """Where shape ``e``'s parameters start in a parameter row."""
        return self.force_offset(len(self.forces)) + _engine.SHP_NP * e

    def plane_offset(self, e: int) -> int:
        """Where plane ``e``'s parameters start in a parameter row."""
        return self.shape_offset(len(self.shapes)) + _engine.PLN_NP * e

    def loop_offset(self, e: int) -> int:
        """Where loop ``e``'s parameters start in a parameter row."""
        return self.plane_offset(len(self.planes)) + _engine.LP_NP * e

    def gear_offset(self, e: int) -> int:
        """Where gear ``e``'s parameters start in a parameter row."""
        return self.loop_offset(len(self.loops)) + _engine.GR_NP * e

    def params(self, g: float, max_drift: float) -> np.ndarray:
        """(np,) the parameter row of the bodies' values (inputs at 0)."""
        p = np.zeros(self.np)
        p[_engine.TP_G] = g
        p[_engine.TP_DRIFT] = max_drift
        p[_engine.TP_GDIR:_engine.TP_GDIR + 3] = self.gravity_dir
        if self.orbit is not None:
            p[_engine.TP_MU] = self.orbit.mu
            p[_engine.TP_ORBIT_R] = self.orbit.radius if self.orbit.circular else 0.0
        for i, b in enumerate(self.bodies):
            o = self.body_offset(i)
            p[o + _engine.TB_POS:o + _engine.TB_POS + 3] = _vec(b.pos)
            Q = _vec(b.rotation, 4)
            p[o + _engine.TB_ROT:o + _engine.TB_ROT + 4] = Q
            p[o + _engine.TB_AXIS:o + _engine.TB_AXIS + 3] = _child_axis(Q, _vec(b.axis))
            p[o + _engine.TB_MASS] = b.mass
            p[o + _engine.TB_CM:o + _engine.TB_CM + 3] = _vec(b.cm)
            J = np.asarray(b.inertia, dtype=float)
            p[o + _engine.TB_I:o + _engine.TB_I + 6] = [J[0, 0], J[1, 1], J[2, 2], J[0, 1], J[0, 2], J[1, 2]]
            p[o + _engine.TB_MOTOR] = b.motor0
            p[o + _engine.TB_STIFF] = b.stiffness
            p[o + _engine.TB_REST] = b.rest_angle
            p[o + _engine.TB_DAMP] = b.damping
            p[o + _engine.TB_KB:o + _engine.TB_KB + 3] = _vec(b.ball_stiffness)
            p[o + _engine.TB_CB:o + _engine.TB_CB + 3] = _vec(b.ball_damping)
            p[o + _engine.TB_LIM] = (b.lower is not None) + 2 * (b.upper is not None) + 4 * (b.stop == "impact")
            p[o + _engine.TB_RESTITUTION] = b.restitution
            p[o + _engine.TB_LO] = b.lower if b.lower is not None else 0.0
            p[o + _engine.TB_HI] = b.upper if b.upper is not None else 0.0
            p[o + _engine.TB_STOP_K] = b.stop_stiffness or 0.0
            p[o + _engine.TB_STOP_C] = b.stop_damping or 0.0
        ko = self.body_offset(len(self.bodies))
        for c, (_, _, k) in enumerate(self.couplings):
            p[ko + c] = k
        for e, s in enumerate(self.springs):
            o = self.spring_offset(e)
            p[o + _engine.SPR_PA:o + _engine.SPR_PA + 3] = _vec(s.point_a)
            p[o + _engine.SPR_PB:o + _engine.SPR_PB + 3] = _vec(s.point_b)
            p[o + _engine.SPR_K], p[o + _engine.SPR_L0], p[o + _engine.SPR_C] = s.stiffness, s.rest_length, s.damping
        for e, f in enumerate(self.forces):
            o = self.force_offset(e)
            p[o + _engine.FRC_P:o + _engine.FRC_P + 3] = _vec(f.point)
        if self.shapes and self.planes:
            for e, h in enumerate(self.shapes):
                o = self.shape_offset(e)
                p[o + _engine.SHP_C:o + _engine.SHP_C + 3] = _vec(h.center)
                p[o + _engine.SHP_R:o + _engine.SHP_R + 9] = np.asarray(h.axes, dtype=float).reshape(9)
                p[o + _engine.SHP_DIM:o + _engine.SHP_DIM + 3] = _vec(h.dims)
            for e, pl in enumerate(self.planes):
                o = self.plane_offset(e)
                p[o + _engine.PLN_P:o + _engine.PLN_P + 3] = _vec(pl.point)
                p[o + _engine.PLN_N:o + _engine.PLN_N + 3] = _vec(pl.normal)
                for k, slot in PLANE_SLOTS.items():
                    p[o + slot] = getattr(pl, k)
        for e, lp in enumerate(self.loops):
            o = self.loop_offset(e)
            for slot, v, k in ((_engine.LP_PA, lp.point_a, 3), (_engine.LP_PB, lp.point_b, 3),
                               (_engine.LP_AA, lp.axis_a, 3), (_engine.LP_AB, lp.axis_b, 3),
                               (_engine.LP_Q0, lp.q0, 4)):
                p[o + slot:o + slot + k] = _vec(v, k)
        for e, gr in enumerate(self.gears):
            p[self.gear_offset(e) + _engine.GR_RATIO] = gr.ratio
        return p

    def state(self) -> np.ndarray:
        """(ny,) the start state of the bodies' values (the monitor's part zero: see ``_engine.tree_start``)."""
        y = np.zeros(self.ny)
        for i, b in enumerate(self.bodies):
            vals = {"q": _vec(b.q0, 4), "omega": _vec(b.omega0), "r": _vec(b.r0), "v": _vec(b.v0)}
            for c in b.coords:
                k = self.coord_slots[(i, c)]
                if c in ("angle", "displacement"):
                    y[k] = b.angle0
                elif c in ("rate", "velocity"):
                    y[k] = b.rate0
                else:
                    head, tail = c.rsplit("_", 1)
                    y[k] = vals[head]["wxyz".index(tail) if head == "q" else "xyz".index(tail)]
        if (None, ORBIT_COORD) in self.coord_slots:
            y[self.coord_slots[(None, ORBIT_COORD)]] = self.orbit.anomaly
        return y
