"""Independent forward-dynamics reference for trees of rigid bodies, built on Pinocchio.

The tree is described in gyrosim's conventions and translated, joint by joint, into a Pinocchio model whose
articulated-body algorithm (``pinocchio.aba``) gives the joint accelerations; these are translated back into
gyrosim's coordinates. Nothing here uses gyrosim's own code, so the tree engine can be tested against it.

Conventions (the contract)
--------------------------
* World frame z up, gravity of magnitude ``g`` along -z.
* Quaternions are ``(w, x, y, z)``, scalar first, unit, and rotate child-frame vectors into the parent frame.
* ``bodies`` is a list of dicts in topological order (a parent comes before its children) with the keys

  ``parent``
      index of the parent body, -1 for the world;
  ``joint``
      one of ``"ball"``, ``"free_rotation"``, ``"hinge"``, ``"free"``, ``"fixed"``;
  ``pos``
      (3,) joint point in the parent's body frame (in the world for a root), which is the origin of the child's
      body frame;
  ``axis``
      (3,) unit hinge axis in the parent frame (hinge only); at angle 0 the child frame is the parent frame, and
      the child frame is the parent frame rotated about ``axis`` by ``angle``;
  ``mass``, ``cm``, ``inertia``
      mass (kg), centre of mass (3,) in the body frame, inertia (3, 3) about the centre of mass in the body frame.

* Joint coordinates (child relative to parent):

  ``ball`` / ``free_rotation``
      ``q`` (4,) and ``omega`` (3,), the relative angular velocity expressed in the child frame;
  ``hinge``
      ``angle`` and ``rate``;
  ``free``
      ``q`` (4,), ``r`` (3,) the child origin relative to ``pos`` in the parent frame, ``omega`` (3,) in the child
      frame, ``v`` (3,) the velocity of the child origin relative to the parent, in the parent frame;
  ``fixed``
      nothing.

* Generalized forces use the joint's velocity coordinates: ball ``torque`` (3,) in the child frame; hinge scalar
  ``torque`` about the axis; free ``torque`` (3,) in the child frame and ``force`` (3,) in the parent frame, applied
  at the child origin. The reaction acts on the parent.
* Sliders (``slider``): one translation along ``axis`` (parent frame), state ``angle`` (the displacement, m) and
  ``rate`` (m/s), generalized force ``torque`` (the force along the axis, N): Pinocchio's
  ``JointModelPrismaticUnaligned``.
* A body's optional ``rotation`` (4,) quaternion turns its joint frame in the parent's (the child's frame at the
  joint's zero): Pinocchio's joint placement gets that rotation, and the joint's axis is given to it in the joint
  frame (``Q^T axis``).
* ``gravity`` may be a 3-vector (world) instead of a magnitude along -z.
* ``point_forces`` of :func:`forward_dynamics`: ``(body, point (3,) body frame, force (3,), world)`` forces at points.
* Springs, damping and couplings (optional keys of a body; :func:`joint_forces` turns them into generalized forces,
  :func:`spring_energy` gives their potential): a hinge's ``stiffness`` k (N*m/rad) about its ``rest_angle``
  and its ``damping`` c (N*m*s/rad) give ``tau = -k (angle - rest_angle) - c rate`` (plus a motor torque); a ball's
  or a free joint's ``damping`` c (N*m*s) gives ``torque = -c omega`` (child frame; a free joint's force is not
  damped). A coupling ``(a, b, k)`` is a torsion spring between hinges ``a`` and ``b``: ``-k (angle_a - angle_b)``
  on ``a``, the opposite on ``b``; potential ``k (angle_a - angle_b)^2 / 2``.
* External torques on bodies (``body_torque`` of :func:`forward_dynamics`): (3,) in the body's frame, acting on
  that body alone (no reaction on the tree).

Pinocchio's conventions, and how they are mapped
------------------------------------------------
* Its configuration vector stores quaternions as ``(x, y, z, w)``.
* ``JointModelSpherical``: velocity is the relative angular velocity in the child (joint) frame, like ours, and its
  acceleration is the time derivative of those components.
* ``JointModelFreeFlyer``: configuration ``(r, quaternion)``, velocity ``(R^T v, omega)``: its linear velocity is in
  the child (LOCAL) frame. Its acceleration ``(a_lin, domega)`` is the derivative of the local components, not the
  classical acceleration, which is ``R (a_lin + omega x R^T v)``. The generalized force is ``(R^T force, torque)``.
* ``JointModelRevoluteUnaligned``: rotation ``exp(angle * axis)`` about an axis of the joint frame; as each joint
  frame is placed with the parent's orientation, the axis in the parent frame is the axis in the joint frame.
* A ``fixed`` body has no joint: its inertia is appended (``Model.appendBodyToJoint``) to the joint its parent
  moves with, at the composed placement, and its children are attached to that joint at the composed placement.
  Bodies fixed to the world are appended to the universe joint; they take no part in the dynamics.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

JOINTS = ("ball", "free_rotation", "hinge", "free", "fixed", "slider")
"""The joint kinds of the contract."""

_SPHERICAL = ("ball", "free_rotation")


@dataclass(frozen=True)
class _Slot:
    """Where a body of the tree lives in the Pinocchio model.

    Attributes
    ----------
    joint_id : int
        The Pinocchio joint the body moves with (its own joint, or an ancestor's for a fixed body; 0 = universe).
    placement : pinocchio.SE3
        The body frame in the frame of ``joint_id`` (identity unless the body is fixed).
    idx_q, idx_v : int
        Offsets of the body's joint in Pinocchio's configuration and velocity vectors (-1 for a fixed body).
    """

    joint_id: int
    placement: pin.SE3
    idx_q: int
    idx_v: int


def _quat_to_pin(q) -> np.ndarray:
    """Convert a quaternion ``(w, x, y, z)`` to Pinocchio's ``(x, y, z, w)`` order, normalized.

    Parameters
    ----------
    q : array_like, shape (4,)
        Quaternion, scalar first.

    Returns
    -------
    numpy.ndarray, shape (4,)
        The unit quaternion, scalar last.
    """
    q = np.asarray(q, dtype=float)
    q = q / np.linalg.norm(q)
    return np.array([q[1], q[2], q[3], q[0]])


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of a quaternion ``(w, x, y, z)`` (child-frame vectors to the parent frame).

    Parameters
    ----------
    q : array_like, shape (4,)
        Quaternion, scalar first; it is normalized.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        ``R`` with ``v_parent = R @ v_child``.
    """
    x, y, z, w = _quat_to_pin(q)
    return pin.Quaternion(w, x, y, z).toRotationMatrix()


def _joint_model(body: dict):
    """The Pinocchio joint model of a body (``None`` for a fixed body).

    Parameters
    ----------
    body : dict
        A body of the tree.

    Returns
    -------
    pinocchio.JointModel or None
        The joint model.

    Raises
    ------
    ValueError
        If the joint kind is unknown.
    """
    kind = body["joint"]
    if kind in _SPHERICAL:
        return pin.JointModelSpherical()
    if kind in ("hinge", "slider"):
        axis = np.asarray(body["axis"], dtype=float)
        axis = quat_to_matrix(body.get("rotation", (1.0, 0.0, 0.0, 0.0))).T @ (axis / np.linalg.norm(axis))
        if kind == "slider":
            return pin.JointModelPrismaticUnaligned(axis)
        return pin.JointModelRevoluteUnaligned(axis)
    if kind == "free":
        return pin.JointModelFreeFlyer()
    if kind == "fixed":
        return None
    raise ValueError(f"unknown joint {kind!r}; expected one of {JOINTS}")


def build_model(bodies: list[dict], g: float = 9.81) -> tuple[pin.Model, list[_Slot]]:
    """Build the Pinocchio model of a tree.

    Parameters
    ----------
    bodies : list of dict
        The tree, in topological order (see the module docstring).
    g : float, optional
        Magnitude of gravity, along -z.

    Returns
    -------
    model : pinocchio.Model
        The model, gravity set to ``(0, 0, -g)``.
    slots : list of _Slot
        Per body, its joint and offsets in the model.

    Raises
    ------
    ValueError
        If a parent does not come before its child, or a joint kind is unknown.
    """
    model = pin.Model()
    gv = np.array([0.0, 0.0, -g]) if np.ndim(g) == 0 else np.asarray(g, dtype=float)
    model.gravity = pin.Motion(gv, np.zeros(3))
    slots: list[_Slot] = []
    for i, body in enumerate(bodies):
        parent = int(body["parent"])
        if not -1 <= parent < i:
            raise ValueError(f"body {i}: parent {parent} must be -1 or an earlier body")
        if parent == -1:
            parent_joint, parent_placement = 0, pin.SE3.Identity()
        else:
            parent_joint, parent_placement = slots[parent].joint_id, slots[parent].placement
        # the joint frame: the parent's body frame translated to the joint point (same orientation)
        rot = quat_to_matrix(body.get("rotation", (1.0, 0.0, 0.0, 0.0)))
        placement = parent_placement * pin.SE3(rot, np.asarray(body["pos"], dtype=float))
        inertia = pin.Inertia(
            float(body["mass"]), np.asarray(body["cm"], dtype=float), np.asarray(body["inertia"], dtype=float)
        )
        joint = _joint_model(body)
        if joint is None:
            model.appendBodyToJoint(parent_joint, inertia, placement)
            slots.append(_Slot(parent_joint, placement, -1, -1))
        else:
            joint_id = model.addJoint(parent_joint, joint, placement, f"body{i}")
            model.appendBodyToJoint(joint_id, inertia, pin.SE3.Identity())
            slots.append(_Slot(joint_id, pin.SE3.Identity(), model.idx_qs[joint_id], model.idx_vs[joint_id]))
    return model, slots


def _pack(bodies: list[dict], model: pin.Model, slots: list[_Slot], state: list[dict], tau=None):
    """Pinocchio's ``q``, ``v`` (and ``tau``) of a state (and generalized forces) in our coordinates.

    Parameters
    ----------
    bodies : list of dict
        The tree.
    model : pinocchio.Model
        Its model, from :func:`build_model`.
    slots : list of _Slot
        Its slots, from :func:`build_model`.
    state : list of dict
        Per body, the joint state.
    tau : list of dict, optional
        Per body, the generalized forces (missing keys or entries are zero).

    Returns
    -------
    q, v, tau : numpy.ndarray
        Configuration (nq,), velocity (nv,) and generalized forces (nv,).
    """
    q = pin.neutral(model)
    v = np.zeros(model.nv)
    t = np.zeros(model.nv)
    tau = tau if tau is not None else [{}] * len(bodies)
    for body, slot, s, f in zip(bodies, slots, state, tau, strict=True):
        f = f or {}
        kind, iq, iv = body["joint"], slot.idx_q, slot.idx_v
        if kind in _SPHERICAL:
            q[iq : iq + 4] = _quat_to_pin(s["q"])
            v[iv : iv + 3] = s["omega"]
            t[iv : iv + 3] = f.get("torque", np.zeros(3))
        elif kind in ("hinge", "slider"):
            q[iq] = s["angle"]
            v[iv] = s["rate"]
            t[iv] = f.get("torque", 0.0)
        elif kind == "free":
            rot = quat_to_matrix(s["q"])
            q[iq : iq + 3] = s["r"]
            q[iq + 3 : iq + 7] = _quat_to_pin(s["q"])
            v[iv : iv + 3] = rot.T @ np.asarray(s["v"], dtype=float)  # LOCAL linear velocity
            v[iv + 3 : iv + 6] = s["omega"]
            t[iv : iv + 3] = rot.T @ np.asarray(f.get("force", np.zeros(3)), dtype=float)
            t[iv + 3 : iv + 6] = f.get("torque", np.zeros(3))
    return q, v, t


def _external_forces(model: pin.Model, slots: list[_Slot], body_torque) -> list:
    """Pinocchio's ``fext`` (one force per joint, in the joint's frame) of torques on bodies (body frames)."""
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for slot, t in zip(slots, body_torque, strict=True):
        if t is None or slot.joint_id == 0:  # a body fixed to the world: the torque goes to the ground
            continue
        # a pure torque: the same about any point, turned from the body frame into its joint's frame
        fext[slot.joint_id] += pin.Force(np.zeros(3), slot.placement.rotation @ np.asarray(t, dtype=float))
    return fext


def _point_forces(model, data, slots, q, point_forces) -> list:
    """Pinocchio's ``fext`` (joint frames) of forces at points of bodies: ``(body, point, force, world)``."""
    pin.forwardKinematics(model, data, q)
    fext = [pin.Force.Zero() for _ in range(model.njoints)]
    for i, pt, f, world in point_forces:
        slot = slots[i]
        R_body = data.oMi[slot.joint_id].rotation @ slot.placement.rotation   # body -> world
        fb = R_body.T @ np.asarray(f, dtype=float) if world else np.asarray(f, dtype=float)
        # (force; torque about the body origin) in the body frame, moved into the joint's frame
        fext[slot.joint_id] += slot.placement.act(pin.Force(fb, np.cross(np.asarray(pt, dtype=float), fb)))
    return fext


def world_points(bodies: list[dict], g, state: list[dict], points) -> list:
    """World position and velocity of points ``(body, point in its frame)`` (body -1: the world), by Pinocchio."""
    model, slots = build_model(bodies, g)
    data = model.createData()
    q, v, _ = _pack(bodies, model, slots, state)
    pin.forwardKinematics(model, data, q, v)
    out = []
    for i, pt in points:
        pt = np.asarray(pt, dtype=float)
        if i < 0:
            out.append((pt, np.zeros(3)))
            continue
        slot = slots[i]
        oMb = data.oMi[slot.joint_id] * slot.placement
        vel = slot.placement.actInv(data.v[slot.joint_id])   # the body's spatial velocity, body frame
        out.append((oMb.act(pt), oMb.rotation @ (vel.linear + np.cross(vel.angular, pt))))
    return out


def forward_dynamics(bodies: list[dict], g: float, state: list[dict], tau: list[dict] | None = None,
                     body_torque: list | None = None, point_forces=()) -> list:
    """Joint accelerations of a tree, in gyrosim's coordinates.

    Parameters
    ----------
    bodies : list of dict
        The tree, in topological order (see the module docstring).
    g : float
        Magnitude of gravity, along -z of the world.
    state : list of dict
        Per body: ball/free_rotation ``{"q": (4,), "omega": (3,)}``, hinge ``{"angle": float, "rate": float}``,
        free ``{"q": (4,), "r": (3,), "omega": (3,), "v": (3,)}``, fixed ``{}``.
    tau : list of dict, optional
        Per body: ball ``{"torque": (3,)}``, hinge ``{"torque": float}``, free ``{"torque": (3,), "force": (3,)}``,
        fixed ``{}``; missing entries are zero.
    body_torque : list, optional
        Per body, an external torque (3,) in its body frame, or None.

    Returns
    -------
    list
        Per body: ball/free_rotation ``domega/dt`` (3,) (child frame components); hinge ``angle''`` (float); free
        the tuple ``(domega/dt (3,) child frame, dv/dt (3,) parent frame)``, ``dv/dt`` being the classical
        acceleration of the child origin relative to the parent frame; fixed ``None``.
    """
    model, slots = build_model(bodies, g)
    data = model.createData()
    q, v, t = _pack(bodies, model, slots, state, tau)
    if not model.nv:
        ddq = np.zeros(0)
    elif point_forces:
        fext = _point_forces(model, data, slots, q, point_forces)
        if body_torque is not None:
            fext = [a + b for a, b in zip(fext, _external_forces(model, slots, body_torque))]
        ddq = pin.aba(model, data, q, v, t, fext)
    elif body_torque is not None:
        ddq = pin.aba(model, data, q, v, t, _external_forces(model, slots, body_torque))
    else:
        ddq = pin.aba(model, data, q, v, t)
    out: list = []
    for body, slot, s in zip(bodies, slots, state, strict=True):
        kind, iv = body["joint"], slot.idx_v
        if kind in _SPHERICAL:
            out.append(np.array(ddq[iv : iv + 3]))
        elif kind in ("hinge", "slider"):
            out.append(float(ddq[iv]))
        elif kind == "free":
            rot = quat_to_matrix(s["q"])
            omega = np.asarray(s["omega"], dtype=float)
            v_local = rot.T @ np.asarray(s["v"], dtype=float)
            # spatial (local) acceleration to the classical one: r'' = R (a_lin + omega x v_local)
            dv = rot @ (ddq[iv : iv + 3] + np.cross(omega, v_local))
            out.append((np.array(ddq[iv + 3 : iv + 6]), dv))
        else:
            out.append(None)
    return out


def energy(bodies: list[dict], g: float, state: list[dict]) -> float:
    """Total mechanical energy: kinetic plus gravitational potential (zero at z = 0).

    Parameters
    ----------
    bodies : list of dict
        The tree.
    g : float
        Magnitude of gravity, along -z.
    state : list of dict
        The joint states.

    Returns
    -------
    float
        ``sum(1/2 v^T M v) + sum(m g z_cm)`` over all bodies, those fixed to the world included.
    """
    model, slots = build_model(bodies, g)
    data = model.createData()
    q, v, _ = _pack(bodies, model, slots, state)
    kinetic = pin.computeKineticEnergy(model, data, q, v)
    potential = pin.computePotentialEnergy(model, data, q)
    # Pinocchio leaves out the bodies on the universe joint (a constant); add them so the value is complete
    world = model.inertias[0]
    gv = np.array([0.0, 0.0, -g]) if np.ndim(g) == 0 else np.asarray(g, dtype=float)
    return float(kinetic + potential - world.mass * gv @ world.lever)


def joint_forces(bodies: list[dict], state: list[dict], couplings=(), motors=None) -> list[dict]:
    """The generalized forces of the springs, the damping, the motors and the couplings at ``state``.

    Parameters
    ----------
    bodies : list of dict
        The tree; a body's optional ``stiffness``, ``rest_angle`` and ``damping`` (see the module docstring).
    state : list of dict
        The joint states.
    couplings : sequence of (int, int, float)
        Torsion springs ``(a, b, k)`` between hinges.
    motors : sequence of float, optional
        Per body, a hinge's motor torque (N*m about its axis; ignored for other joints).

    Returns
    -------
    list of dict
        ``tau`` for :func:`forward_dynamics`: hinge ``-k (angle - rest_angle) - c rate + motor`` and the couplings'
        ``-k (angle_a - angle_b)`` on a, ``+k (angle_a - angle_b)`` on b; ball, free_rotation and free
        ``torque = -c omega``.
    """
    tau: list[dict] = []
    for i, (body, s) in enumerate(zip(bodies, state, strict=True)):
        kind, c = body["joint"], float(body.get("damping", 0.0))
        if kind == "hinge":
            k, rest = float(body.get("stiffness", 0.0)), float(body.get("rest_angle", 0.0))
            motor = float(motors[i]) if motors is not None else 0.0
            tau.append({"torque": motor - k * (s["angle"] - rest) - c * s["rate"]})
        elif kind in (*_SPHERICAL, "free"):
            tau.append({"torque": -c * np.asarray(s["omega"], dtype=float)})
        else:
            tau.append({})
    for a, b, k in couplings:
        if bodies[a]["joint"] != "hinge" or bodies[b]["joint"] != "hinge":
            raise ValueError(f"coupling ({a}, {b}): both bodies must be hinges")
        m = k * (state[a]["angle"] - state[b]["angle"])
        tau[a]["torque"] -= m
        tau[b]["torque"] += m
    return tau


def spring_energy(bodies: list[dict], state: list[dict], couplings=()) -> float:
    """The springs' potential: ``sum k (angle - rest_angle)^2 / 2`` over hinges plus ``sum k (angle_a -
    angle_b)^2 / 2`` over couplings (J)."""
    e = 0.0
    for body, s in zip(bodies, state, strict=True):
        if body["joint"] == "hinge":
            e += 0.5 * float(body.get("stiffness", 0.0)) * (s["angle"] - float(body.get("rest_angle", 0.0))) ** 2
    for a, b, k in couplings:
        e += 0.5 * k * (state[a]["angle"] - state[b]["angle"]) ** 2
    return e


def random_springs(rng: np.random.Generator, bodies: list[dict]) -> tuple[list[dict], list[tuple[int, int, float]]]:
    """Springs, damping and couplings for a tree.

    Each hinge gets ``stiffness`` in [0, 20] N*m/rad about a ``rest_angle`` in [-pi, pi]; each hinge, ball,
    free_rotation and free joint a ``damping`` in [0, 2] (N*m*s/rad or N*m*s); a quarter of each are 0 instead.
    With two hinges or more, 1 to 3 couplings between random distinct hinges, stiffness in [0.5, 10] N*m/rad.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    bodies : list of dict
        The tree (not changed).

    Returns
    -------
    bodies : list of dict
        Copies of the bodies with ``stiffness``, ``rest_angle`` and ``damping``.
    couplings : list of (int, int, float)
        ``(a, b, k)``.
    """

    def maybe(lo, hi):
        return 0.0 if rng.random() < 0.25 else float(rng.uniform(lo, hi))

    out = []
    for body in bodies:
        b = dict(body)
        if b["joint"] == "hinge":
            b.update(stiffness=maybe(0.0, 20.0), rest_angle=float(rng.uniform(-np.pi, np.pi)))
        if b["joint"] != "fixed":
            b["damping"] = maybe(0.0, 2.0)
        out.append(b)
    hinges = [i for i, b in enumerate(bodies) if b["joint"] == "hinge"]
    couplings = []
    if len(hinges) >= 2:
        for _ in range(int(rng.integers(1, 4))):
            a, b = rng.choice(hinges, size=2, replace=False)
            couplings.append((int(a), int(b), float(rng.uniform(0.5, 10.0))))
    return out, couplings


def momentum_world(bodies: list[dict], state: list[dict]) -> np.ndarray:
    """Total angular momentum about the world origin, in the world frame.

    Parameters
    ----------
    bodies : list of dict
        The tree.
    state : list of dict
        The joint states.

    Returns
    -------
    numpy.ndarray, shape (3,)
        ``sum(c_i x m_i v_ci + R_i I_i omega_i)`` over the bodies (world-frame centres of mass ``c_i``).
    """
    model, slots = build_model(bodies)
    data = model.createData()
    q, v, _ = _pack(bodies, model, slots, state)
    pin.forwardKinematics(model, data, q, v)
    total = np.zeros(3)
    for j in range(1, model.njoints):
        # spatial momentum in the joint frame, moved to the world frame (moment about the world origin)
        total += data.oMi[j].act(model.inertias[j] * data.v[j]).angular
    return total


def random_rotation(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random unit quaternion ``(w, x, y, z)`` with ``w >= 0``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    numpy.ndarray, shape (4,)
        The quaternion.
    """
    q = rng.standard_normal(4)
    q /= np.linalg.norm(q)
    return q if q[0] >= 0 else -q


def _random_unit(rng: np.random.Generator) -> np.ndarray:
    """A uniformly random unit vector of R^3."""
    u = rng.standard_normal(3)
    return u / np.linalg.norm(u)


def _random_rate(rng: np.random.Generator) -> float:
    """A random rate of magnitude in [1, 10] rad/s and random sign."""
    return float(rng.choice((-1.0, 1.0)) * rng.uniform(1.0, 10.0))


def random_inertia(rng: np.random.Generator, mass: float) -> np.ndarray:
    """A random physical inertia tensor (SPD, principal moments satisfying the triangle inequality).

    The principal moments come from random second moments ``s`` of the mass distribution,
    ``I1 = s2 + s3`` and so on, so ``I1 + I2 >= I3`` holds (strictly) and the tensor is SPD; it is then rotated
    by a random rotation.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    mass : float
        Mass of the body (kg); the second moments scale with it.

    Returns
    -------
    numpy.ndarray, shape (3, 3)
        Inertia about the centre of mass.
    """
    s = mass * rng.uniform(0.002, 0.05, 3)
    principal = np.array([s[1] + s[2], s[0] + s[2], s[0] + s[1]])
    rot = quat_to_matrix(random_rotation(rng))
    inertia = rot @ np.diag(principal) @ rot.T
    return 0.5 * (inertia + inertia.T)


def random_tree(rng: np.random.Generator, n: int, root_joint: str | None = None) -> list[dict]:
    """A random valid tree of ``n`` bodies.

    Body 0 is the only root (a free, ball or hinge joint to the world); each later body hangs from the previous
    one (a chain) with probability 0.6, else from a random earlier body (a branch), through a hinge, ball,
    free_rotation or fixed joint. Masses are in [0.1, 5] kg; ``free_rotation`` bodies have ``cm = 0``.

    Parameters
    ----------
    rng : numpy.random.Generator
        Random source.
    n : int
        Number of bodies (>= 1).
    root_joint : str, optional
        Joint of the root (``"free"``, ``"ball"``, ``"hinge"``, ...); random among the first three by default.

    Returns
    -------
    list of dict
        The bodies, in topological order.
    """
    if n < 1:
        raise ValueError("a tree has at least one body")
    bodies: list[dict] = []
    for i in range(n):
        if i == 0:
            parent = -1
            joint = root_joint or str(rng.choice(["free", "ball", "hinge"]))
        else:
            parent = i - 1 if rng.random() < 0.6 else int(rng.integers(0, i))
            joint = str(rng.choice(["hinge", "ball", "free_rotation", "fixed"], p=[0.45, 0.25, 0.15, 0.15]))
        mass = float(rng.uniform(0.1, 5.0))
        cm = np.zeros(3) if joint == "free_rotation" else rng.uniform(-0.3, 0.3, 3)
        bodies.append(
            {
                "parent": parent,
                "joint": joint,
                "pos": rng.uniform(-0.5, 0.5, 3),
                "axis": _random_unit(rng),
                "mass": mass,
                "cm": cm,
                "inertia": random_inertia(rng, mass),
            }
        )
    return bodies


def random_state(bodies: list[dict], rng: np.random.Generator) -> list[dict]:
    """A random valid state of a tree.

    Unit quaternions, angular rates of magnitude 1-10 rad/s, hinge angles in [-pi, pi], free-joint offsets in
    [-1, 1] m and velocities in [-2, 2] m/s.

    Parameters
    ----------
    bodies : list of dict
        The tree.
    rng : numpy.random.Generator
        Random source.

    Returns
    -------
    list of dict
        Per body, the joint state (see :func:`forward_dynamics`).
    """
    state: list[dict] = []
    for body in bodies:
        kind = body["joint"]
        if kind in _SPHERICAL:
            state.append({"q": random_rotation(rng), "omega": _random_unit(rng) * rng.uniform(1.0, 10.0)})
        elif kind == "hinge":
            state.append({"angle": float(rng.uniform(-np.pi, np.pi)), "rate": _random_rate(rng)})
        elif kind == "free":
            state.append(
                {
                    "q": random_rotation(rng),
                    "r": rng.uniform(-1.0, 1.0, 3),
                    "omega": _random_unit(rng) * rng.uniform(1.0, 10.0),
                    "v": rng.uniform(-2.0, 2.0, 3),
                }
            )
        elif kind == "fixed":
            state.append({})
        elif kind == "slider":
            state.append({"angle": float(rng.uniform(-1.0, 1.0)), "rate": float(rng.uniform(-2.0, 2.0))})
        else:
            raise ValueError(f"unknown joint {kind!r}; expected one of {JOINTS}")
    return state
