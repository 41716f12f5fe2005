"""The frames of a tree scene as the service publishes them: each body's transform from its parent frame.

A tree scene (docs/trees.md) publishes, for every body, the transform parent -> body (``tf``, ``frame_id``
the parent body's name or ``world`` for a root), the body's attitude in the world and its angular velocity
(``state``, ``imu``). :class:`TreeFrames` reads them off a tree :class:`gyrosim.model.Model`'s outputs:

* translation: the joint point ``pos`` in the parent frame (the parameters ``<body>.pos_x..z``), plus the
  position ``r`` of a ``free`` joint or a slider's ``displacement`` along its axis;
* rotation (child -> parent, ``(w, x, y, z)``): the joint's placement ``rotation`` Q, then a hinge's rotation about
  its axis by its angle (Rot(axis, angle) Q, the axis in the parent frame), a ball's / free_rotation's quaternion
  (Q q), a free joint's q; Q alone for ``fixed`` and ``slider``;
* the world attitude: the model's ``<body>.q_world_*``;
* the angular velocity relative to the world in the body's own frame (what a gyro on the body measures), composed
  down the tree: ``omega_i = R_rel^T omega_parent + the joint's rate`` (``axis * rate`` for a hinge, the joint's
  ``omega`` for a ball or free joint, 0 for fixed), as the engine composes the bodies' velocities.

A scene with contact (``[[shape]]`` and ``[[plane]]`` tables, :mod:`gyrosim.scene_contact`) also has one frame per
contact, shape and plane (:class:`ContactFrame`, :attr:`TreeFrames.contacts`), published in the ``tf`` of the body
that carries the shape: from ``world``, named ``<body>/<shape>/contact`` (``<body>/<shape>/<plane>/contact`` in a
scene of several planes; :func:`contact_frame_id`), its origin the contact point (the model's ``<shape>.contact_x..z``,
world, m), its axes the world's turned so that its z is the plane's normal (the identity for a floor of normal +z).

Plain Python floats: a few microseconds per body and step, no arrays to allocate.

Examples
--------
>>> from gyrosim.model import Model
>>> m = Model("gimbal_gyroscope")
>>> frames = TreeFrames(m)
>>> [(f.parent, f.name) for f in frames.bodies]
[('world', 'outer'), ('outer', 'inner'), ('inner', 'rotor')]
>>> rotor = frames.at(m.outputs())[2]
>>> [round(v, 9) for v in rotor.omega]
[0.0, 0.0, 200.0]
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..telemetry.messages import WORLD_FRAME

__all__ = ["BodyFrame", "FrameState", "TreeFrames", "SCENE_OUTPUTS", "ContactFrame", "contact_frame_id",
           "contact_frames", "CONTACT_STATE", "normal_rotation"]

#: The scene-wide outputs of a tree scene a BodyState carries.
SCENE_OUTPUTS = ("energy", "energy_error", "L_x", "L_y", "L_z")

#: The contact outputs a BodyState carries for each contact of its body (``contacts``), with the contact point (in
#: the ``tf``): the short names of :data:`gyrosim.core.tree.CONTACT_OUTPUTS`.
CONTACT_STATE = ("gap", "normal_force", "slip_speed", "mode")

_IDENTITY = (1.0, 0.0, 0.0, 0.0)


def contact_frame_id(body: str, shape: str, plane: str | None = None) -> str:
    """The tf frame of a contact point: ``<body>/<shape>/contact``, with several planes
    ``<body>/<shape>/<plane>/contact``.

    Body, shape and plane names hold no ``/`` (letters, digits, ``_``, ``-``), so a contact's frame differs from
    every body's frame and every other contact's; no leading ``/`` (tf2 refuses one).

    Examples
    --------
    >>> contact_frame_id("top", "ball"), contact_frame_id("top", "stem", "wall")
    ('top/ball/contact', 'top/stem/wall/contact')
    """
    return f"{body}/{shape}/contact" if plane is None else f"{body}/{shape}/{plane}/contact"


def normal_rotation(normal) -> tuple:
    """The unit quaternion ``(w, x, y, z)`` of the shortest rotation taking the world's z onto ``normal`` (unit):
    a contact frame's rotation from the world, its z the plane's normal; the identity for ``(0, 0, 1)``, a half turn
    about x for ``(0, 0, -1)``.

    Examples
    --------
    >>> normal_rotation((0.0, 0.0, 1.0))
    (1.0, 0.0, 0.0, 0.0)
    """
    nx, ny, nz = (float(v) for v in normal)
    if nx == 0.0 and ny == 0.0:
        # along z: the identity, or for -z a half turn about x
        return _IDENTITY if nz > 0.0 else (0.0, 1.0, 0.0, 0.0)
    norm = math.sqrt(nx * nx + ny * ny + nz * nz)
    nx, ny, nz = nx / norm, ny / norm, nz / norm
    # (1 + z.n, z x n), normalized; 1 + nz as (nx^2 + ny^2) / (1 - nz) near -z, where 1 + nz cancels
    w = 1.0 + nz if nz >= 0.0 else (nx * nx + ny * ny) / (1.0 - nz)
    x, y = (-ny if ny else 0.0), nx
    n = math.sqrt(w * w + x * x + y * y)
    return (w / n, x / n, y / n, 0.0)


@dataclass(frozen=True)
class ContactFrame:
    """One contact (a shape against a plane) as the service publishes it.

    Attributes
    ----------
    body : str
        The body that carries the shape (its ``tf`` and ``state`` carry the contact).
    body_index : int
        The body's index in the model's bodies.
    shape, plane : str
        The shape's and the plane's names.
    frame_id : str
        The contact point's tf frame (:func:`contact_frame_id`), child of ``world``.
    rotation : (4,) tuple of float
        The frame's rotation from the world ``(w, x, y, z)``: its z the plane's normal (:func:`normal_rotation`).
    point_keys : (3,) tuple of str
        The model's outputs of the contact point, world, m (``<shape>.contact_x..z``, full names).
    value_keys : tuple of str
        The model's outputs of :data:`CONTACT_STATE` (full names), in that order.
    """

    body: str
    body_index: int
    shape: str
    plane: str
    frame_id: str
    rotation: tuple
    point_keys: tuple
    value_keys: tuple


def contact_frames(scene) -> list[ContactFrame]:
    """Every contact of a tree scene, in the engine's order (:func:`gyrosim.kernel_tree.contact_stems`)."""
    if not getattr(scene, "shapes", ()):
        return []
    from ..kernel_tree import contact_stems

    names = [b.name for b in scene.tree]
    several = len(scene.planes) > 1
    planes = {pl.name: pl for pl in scene.planes}
    out = []
    for h, stem in contact_stems(scene):
        body = names[h.body]
        plane = stem.rsplit(".", 1)[1] if several else scene.planes[0].name
        name = scene.var_name
        out.append(ContactFrame(
            body=body, body_index=int(h.body), shape=h.name, plane=plane,
            frame_id=contact_frame_id(body, h.name, plane if several else None),
            rotation=normal_rotation(planes[plane].normal),
            point_keys=tuple(name(body, f"{stem}.contact_{c}") for c in "xyz"),
            value_keys=tuple(name(body, f"{stem}.{q}") for q in CONTACT_STATE)))
    return out


@dataclass(frozen=True)
class BodyFrame:
    """What does not change about one body's frame.

    Attributes
    ----------
    name : str
        The body (and its frame).
    parent : str
        The parent frame: the parent body's name, ``world`` for a root.
    parent_index : int
        Index of the parent body, -1 for the world.
    joint : str
        ``hinge``, ``ball``, ``free_rotation``, ``free`` or ``fixed``.
    coords : tuple of str
        The joint's variables (``angle``, ``rate``; ``q_w``.. ``omega_x``..; ``r_x``.. ``v_x``..).
    axis : (3,) tuple of float
        Unit hinge or slider axis, parent frame.
    pos : (3,) tuple of float
        The joint point in the parent frame, m.
    placement : (4,) tuple of float
        The joint's placement Q (the child's frame at the joint's zero in the parent's).
    """

    name: str
    parent: str
    parent_index: int
    joint: str
    coords: tuple
    axis: tuple
    pos: tuple
    placement: tuple = (1.0, 0.0, 0.0, 0.0)


@dataclass(frozen=True)
class FrameState:
    """One body's frame at one time.

    Attributes
    ----------
    translation : (3,) tuple of float
        Origin of the body frame in the parent frame, m.
    rotation : (4,) tuple of float
        Unit quaternion ``(w, x, y, z)`` rotating body-frame vectors into the parent frame.
    q_world : (4,) tuple of float
        The body's attitude in the world (the model's ``q_world``).
    omega : (3,) tuple of float
        Angular velocity relative to the world, body frame, rad/s.
    joint : dict
        The joint's variables by their short names.
    """

    translation: tuple
    rotation: tuple
    q_world: tuple
    omega: tuple
    joint: dict


def _rotate_inverse(q, v):
    """``R(q)^T v`` for a unit quaternion ``q = (w, x, y, z)``: v from the parent frame into the child frame."""
    w, x, y, z = q[0], -q[1], -q[2], -q[3]
    tx = 2.0 * (y * v[2] - z * v[1])
    ty = 2.0 * (z * v[0] - x * v[2])
    tz = 2.0 * (x * v[1] - y * v[0])
    return (v[0] + w * tx + (y * tz - z * ty),
            v[1] + w * ty + (z * tx - x * tz),
            v[2] + w * tz + (x * ty - y * tx))


def _mul(a, b):
    """The quaternion product a b (w, x, y, z); b itself where a is the identity (the bits of the joint alone)."""
    if a == _IDENTITY:
        return b
    if b == _IDENTITY:
        return a
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return (w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2, w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2, w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2)


def _unit(q):
    n = math.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
    return tuple(v / n for v in q) if n > 0 else _IDENTITY


class TreeFrames:
    """The frames of a tree model's bodies (topological order: a parent before its children).

    Parameters
    ----------
    model : gyrosim.model.Model
        The model; its joint points are read once (``<body>.pos_x..z``, after any ``--set``).
    """

    def __init__(self, model):
        tree = model.scene.tree
        names = list(model.body_names)
        self.bodies: list[BodyFrame] = []
        for b in tree:
            pos = tuple(float(model.get(model.scene.var_name(b.name, f"pos_{c}"))) for c in "xyz")
            self.bodies.append(BodyFrame(
                name=b.name, parent=WORLD_FRAME if b.parent < 0 else names[b.parent], parent_index=int(b.parent),
                joint=b.joint, coords=tuple(b.coords), axis=tuple(float(v) for v in b.axis), pos=pos,
                placement=tuple(float(v) for v in b.rotation)))
        name = model.scene.var_name
        self._keys = [(tuple(name(f.name, c) for c in f.coords),
                       tuple(name(f.name, f"q_world_{c}") for c in "wxyz")) for f in self.bodies]
        #: the scene's contacts (shape against plane), none without ``[[shape]]`` tables
        self.contacts: list[ContactFrame] = contact_frames(model.scene)

    def at(self, outputs: dict) -> list[FrameState]:
        """Every body's frame from the model's outputs (``model.outputs()``, full names)."""
        states: list[FrameState] = []
        for f, (coord_keys, qw_keys) in zip(self.bodies, self._keys):
            joint = {c: outputs[k] for c, k in zip(f.coords, coord_keys)}
            translation = f.pos
            Q = f.placement
            if f.joint == "hinge":
                half = 0.5 * joint["angle"]
                s = math.sin(half)
                rotation = _mul((math.cos(half), s * f.axis[0], s * f.axis[1], s * f.axis[2]), Q)
                rate = joint["rate"]
                a = _rotate_inverse(Q, f.axis)   # the axis in the child frame
                omega_joint = (a[0] * rate, a[1] * rate, a[2] * rate)
            elif f.joint in ("ball", "free_rotation", "free"):
                rotation = _mul(Q, _unit((joint["q_w"], joint["q_x"], joint["q_y"], joint["q_z"])))
                omega_joint = (joint["omega_x"], joint["omega_y"], joint["omega_z"])
                if f.joint == "free":
                    translation = (f.pos[0] + joint["r_x"], f.pos[1] + joint["r_y"], f.pos[2] + joint["r_z"])
            elif f.joint == "slider":
                rotation = Q
                d = joint["displacement"]
                translation = (f.pos[0] + d * f.axis[0], f.pos[1] + d * f.axis[1], f.pos[2] + d * f.axis[2])
                omega_joint = (0.0, 0.0, 0.0)
            else:  # fixed
                rotation = Q
                omega_joint = (0.0, 0.0, 0.0)
            if f.parent_index < 0:
                omega = omega_joint
            else:
                w = _rotate_inverse(rotation, states[f.parent_index].omega)
                omega = (w[0] + omega_joint[0], w[1] + omega_joint[1], w[2] + omega_joint[2])
            states.append(FrameState(translation=translation, rotation=rotation,
                                     q_world=tuple(outputs[k] for k in qw_keys), omega=omega, joint=joint))
        return states
