"""Message encodings of the gyrosim service and recordings: the only module that knows them.

=======  ============================================  ==================================================
kind     Zenoh encoding                                MCAP channel: message encoding, schema (encoding)
=======  ============================================  ==================================================
state    ``application/json;gyrosim.BodyState``        json, gyrosim.BodyState (jsonschema)
tf       ``application/cdr;tf2_msgs/msg/TFMessage``    cdr, tf2_msgs/msg/TFMessage (ros2msg)
imu      ``application/cdr;sensor_msgs/msg/Imu``       cdr, sensor_msgs/msg/Imu (ros2msg)
torque   ``application/json`` ``{"x", "y", "z"}``      json, gyrosim.Torque (jsonschema)
motor    ``application/json`` ``{"torque"}``           json, gyrosim.MotorTorque (jsonschema)
params   ``application/json`` (query reply)            -
=======  ============================================  ==================================================

CDR payloads are encoded from the same ROS 2 message definition text that goes into the MCAP schema (the
concatenated form rosbag2 writes, with ``MSG: pkg/Type`` sections), so Foxglove and ``mcap-ros2-support``
decode them. Every header stamp is the simulation time; ``publish_time`` of an MCAP message is the same time
in ns (:func:`sim_time_ns` reads it back from any payload kind).

Examples
--------
>>> from gyrosim.telemetry import messages as msg
>>> data = msg.encode_imu(1.5, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 10.0), frame_id="gyro")
>>> imu = msg.decode_cdr(msg.IMU_TYPE, data)
>>> imu.header.stamp.sec, imu.header.stamp.nanosec, imu.angular_velocity.z
(1, 500000000, 10.0)
>>> msg.sim_time_ns(msg.IMU_ENCODING, data)
1500000000
>>> msg.parse_torque(b'{"x": 0.1, "y": 0, "z": -2}', limit=5.0)
Torque(x=0.1, y=0.0, z=-2.0)
>>> msg.parse_motor(b'{"torque": 0.05}', limit=5.0)
MotorTorque(torque=0.05)
"""

from __future__ import annotations

import json
import math
import struct
from dataclasses import dataclass, field
from functools import cache
from typing import Any

from ..errors import ConfigError

__all__ = [
    "STATE_ENCODING",
    "TF_ENCODING",
    "IMU_ENCODING",
    "TORQUE_ENCODING",
    "MOTOR_ENCODING",
    "PARAMS_ENCODING",
    "STATE_SCHEMA_NAME",
    "TORQUE_SCHEMA_NAME",
    "MOTOR_SCHEMA_NAME",
    "MOTOR_FORCE_SCHEMA_NAME",
    "MOTOR_FORCE_ENCODING",
    "MOTOR_FORCE_JSON_SCHEMA",
    "MotorForce",
    "parse_motor_force",
    "encode_motor_force",
    "DEFAULT_FORCE_LIMIT",
    "TF_TYPE",
    "IMU_TYPE",
    "TF_MSGDEF",
    "IMU_MSGDEF",
    "BODY_STATE_JSON_SCHEMA",
    "TORQUE_JSON_SCHEMA",
    "MOTOR_JSON_SCHEMA",
    "FRAME_TRANSFORM_SCHEMA_NAME",
    "FRAME_TRANSFORM_JSON_SCHEMA",
    "STATE_INPUTS",
    "JOINT_VARIABLES",
    "CONTACT_MODES",
    "CONTACT_VALUES",
    "WORLD_FRAME",
    "DEFAULT_TORQUE_LIMIT",
    "BodyState",
    "ChannelSchema",
    "Torque",
    "TorqueRejected",
    "MotorTorque",
    "MotorRejected",
    "seconds_to_ns",
    "ns_to_stamp",
    "encode_state",
    "decode_state",
    "encode_tf",
    "encode_imu",
    "encode_frame_transform",
    "decode_cdr",
    "encode_torque",
    "parse_torque",
    "encode_motor",
    "parse_motor",
    "encode_params",
    "sim_time_ns",
    "stamp_and_seq",
    "schema_for_encoding",
    "encoding_for_channel",
]

# --------------------------------------------------------------------------------------------- encodings
STATE_SCHEMA_NAME = "gyrosim.BodyState"
TORQUE_SCHEMA_NAME = "gyrosim.Torque"
MOTOR_SCHEMA_NAME = "gyrosim.MotorTorque"
MOTOR_FORCE_SCHEMA_NAME = "gyrosim.MotorForce"
TF_TYPE = "tf2_msgs/msg/TFMessage"
IMU_TYPE = "sensor_msgs/msg/Imu"
#: The ROS 2 types of the ROS 2 side (``gyrosim serve --ros-domain``): the simulation clock, hinge joint states, and
#: the commands taken from ROS 2 topics.
CLOCK_TYPE = "rosgraph_msgs/msg/Clock"
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"
WRENCH_TYPE = "geometry_msgs/msg/Wrench"
WRENCH_STAMPED_TYPE = "geometry_msgs/msg/WrenchStamped"
FLOAT64_TYPE = "std_msgs/msg/Float64"

STATE_ENCODING = f"application/json;{STATE_SCHEMA_NAME}"
TF_ENCODING = f"application/cdr;{TF_TYPE}"
IMU_ENCODING = f"application/cdr;{IMU_TYPE}"
TORQUE_ENCODING = "application/json"
MOTOR_ENCODING = "application/json"
#: A slider's motor command ``{"force"}`` (N): its own schema, named in the encoding (a hinge's is ``{"torque"}``).
MOTOR_FORCE_ENCODING = f"application/json;{MOTOR_FORCE_SCHEMA_NAME}"
PARAMS_ENCODING = "application/json"

#: Parent frame of every transform.
WORLD_FRAME = "world"
#: Default largest accepted |torque component|, N*m.
DEFAULT_TORQUE_LIMIT = 100.0
#: Default largest accepted |motor force| of a slider's motor command, N.
DEFAULT_FORCE_LIMIT = 1000.0

# ------------------------------------------------------------------------------ ROS 2 message definitions
_SEP = "=" * 80 + "\n"

_HEADER = """\
# Standard metadata for higher-level stamped data types.
builtin_interfaces/Time stamp
string frame_id
"""
_TIME = """\
int32 sec
uint32 nanosec
"""
_VECTOR3 = """\
float64 x
float64 y
float64 z
"""
_QUATERNION = """\
float64 x 0
float64 y 0
float64 z 0
float64 w 1
"""
_TRANSFORM = """\
Vector3 translation
Quaternion rotation
"""
_TRANSFORM_STAMPED = """\
std_msgs/Header header
string child_frame_id
Transform transform
"""


def _concat(top: str, deps: list[tuple[str, str]]) -> str:
    parts = [top]
    for name, text in deps:
        parts.append(_SEP + f"MSG: {name}\n" + text)
    return "".join(parts)


#: Full ros2msg definition of tf2_msgs/msg/TFMessage, dependencies appended as rosbag2 does.
TF_MSGDEF = _concat(
    "geometry_msgs/TransformStamped[] transforms\n",
    [
        ("geometry_msgs/TransformStamped", _TRANSFORM_STAMPED),
        ("std_msgs/Header", _HEADER),
        ("builtin_interfaces/Time", _TIME),
        ("geometry_msgs/Transform", _TRANSFORM),
        ("geometry_msgs/Vector3", _VECTOR3),
        ("geometry_msgs/Quaternion", _QUATERNION),
    ],
)

#: Full ros2msg definition of sensor_msgs/msg/Imu, dependencies appended as rosbag2 does.
IMU_MSGDEF = _concat(
    """\
# Covariances are row major about x, y, z. All zeros: covariance unknown.
# Element 0 = -1: the quantity is not provided (and its values are to be ignored).
std_msgs/Header header
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
""",
    [
        ("std_msgs/Header", _HEADER),
        ("builtin_interfaces/Time", _TIME),
        ("geometry_msgs/Quaternion", _QUATERNION),
        ("geometry_msgs/Vector3", _VECTOR3),
    ],
)

#: Full ros2msg definition of rosgraph_msgs/msg/Clock (the simulation time, for ``use_sim_time`` nodes).
CLOCK_MSGDEF = _concat("builtin_interfaces/Time clock\n", [("builtin_interfaces/Time", _TIME)])

#: Full ros2msg definition of sensor_msgs/msg/JointState.
JOINT_STATE_MSGDEF = _concat(
    """\
std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort
""",
    [("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME)],
)

#: Full ros2msg definition of geometry_msgs/msg/Wrench (a torque command: its torque part, N*m, body frame).
WRENCH_MSGDEF = _concat("Vector3 force\nVector3 torque\n", [("geometry_msgs/Vector3", _VECTOR3)])

#: Full ros2msg definition of geometry_msgs/msg/WrenchStamped.
WRENCH_STAMPED_MSGDEF = _concat(
    "std_msgs/Header header\nWrench wrench\n",
    [("std_msgs/Header", _HEADER), ("builtin_interfaces/Time", _TIME),
     ("geometry_msgs/Wrench", "Vector3 force\nVector3 torque\n"), ("geometry_msgs/Vector3", _VECTOR3)],
)

#: Full ros2msg definition of std_msgs/msg/Float64 (a motor torque command, N*m).
FLOAT64_MSGDEF = "float64 data\n"

_MSGDEFS = {TF_TYPE: TF_MSGDEF, IMU_TYPE: IMU_MSGDEF, CLOCK_TYPE: CLOCK_MSGDEF, JOINT_STATE_TYPE: JOINT_STATE_MSGDEF,
            WRENCH_TYPE: WRENCH_MSGDEF, WRENCH_STAMPED_TYPE: WRENCH_STAMPED_MSGDEF, FLOAT64_TYPE: FLOAT64_MSGDEF}


def msgdef(type_name: str) -> str:
    """The full ros2msg definition this module publishes for ``type_name`` (dependencies appended)."""
    return _MSGDEFS[type_name]

# ------------------------------------------------------------------------------------------ JSON schemas
# Foxglove's JSON-schema reader (parseJsonSchema) takes one type name per field (no ["number", "null"]) and needs
# "properties" on every object; it throws on the whole channel otherwise. So every field has a single type and a
# value that is not available is still written as null (the reader accepts null values). Checked by
# gyrosim.telemetry.foxglove_schema.check_foxglove_schema in the tests, and by `gyrosim mcap info`.
_NUM = {"type": "number"}


def _vec(n: int, what: str) -> dict:
    return {"type": "array", "items": _NUM, "minItems": n, "maxItems": n, "description": what}


def _num(what: str) -> dict:
    return {"type": "number", "description": what + " (null when not available or not finite)"}


#: Input names a BodyState's ``inputs`` object may carry: body-frame torque and a hinge's motor torque, N*m; a
#: slider's motor force, N.
STATE_INPUTS = ("tau_x", "tau_y", "tau_z", "motor_torque", "motor_force")

_INPUT_DESCRIPTIONS = {"tau_x": "body-frame torque x, N*m", "tau_y": "body-frame torque y, N*m",
                       "tau_z": "body-frame torque z, N*m",
                       "motor_torque": "hinge motor torque about the joint axis, N*m (tree scenes)",
                       "motor_force": "slider motor force along the joint axis, N (tree scenes)"}

#: The joint variables a tree body's BodyState carries in ``joint`` (docs/trees.md), with unit and meaning; a body
#: has those of its joint only (hinge: angle, rate; ball and free_rotation: q, omega; free: also r, v; fixed: none).
JOINT_VARIABLES = {
    "angle": ("rad", "hinge angle (unwrapped)"),
    "rate": ("rad/s", "hinge rate"),
    "displacement": ("m", "slider displacement along its axis"),
    "velocity": ("m/s", "slider velocity along its axis"),
    **{f"q_{c}": ("1", f"attitude relative to the parent, {c} part of (w, x, y, z)") for c in "wxyz"},
    **{f"omega_{c}": ("rad/s", f"angular velocity relative to the parent, body {c}") for c in "xyz"},
    **{f"r_{c}": ("m", f"position of the body's origin, world {c} (free joint)") for c in "xyz"},
    **{f"v_{c}": ("m/s", f"velocity of the body's origin, world {c} (free joint)") for c in "xyz"},
}

#: The contact modes (a contact's ``mode``; gyrosim.core.tree.CONTACT_MODES).
CONTACT_MODES = ("apart", "sliding", "rolling", "resting")

#: The values a BodyState's ``contacts`` carry for each contact (the model's ``<shape>.<name>``), with their meaning.
CONTACT_VALUES = {
    "gap": "distance of the shape above the plane, m (negative: penetration)",
    "normal_force": "normal force of the plane on the shape, N",
    "slip_speed": "speed of the body's point at the contact along the plane, m/s",
    "mode": "contact mode: 0 apart, 1 sliding, 2 rolling, 3 resting",
}

#: JSON Schema (draft 2020-12) of a BodyState message.
BODY_STATE_JSON_SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": STATE_SCHEMA_NAME,
    "description": "State of one rigid body of a gyrosim scene at simulation time t (SI units).",
    "type": "object",
    "properties": {
        "t": {"type": "number", "description": "simulation time, s"},
        "seq": {"type": "integer", "minimum": 0, "description": "per-body message counter from 0"},
        "scene": {"type": "string"},
        "body": {"type": "string"},
        "q": _vec(4, "attitude quaternion (w, x, y, z), body -> world (a tree body: its world attitude q_world)"),
        "omega": _vec(3, "body-frame angular velocity relative to the world (what a gyro on the body measures), "
                         "rad/s"),
        "phi": _num("ZYZ precession angle (unwrapped), rad"),
        "theta": _num("ZYZ nutation angle in [0, pi], rad"),
        "psi": _num("ZYZ spin angle (unwrapped), rad"),
        "L": {**_vec(3, "world-frame angular momentum about the reference point, kg*m^2/s "
                        "(null when the scene has no L output; a tree scene: the whole tree's)")},
        "energy": _num("total energy, J (a tree scene: the whole tree's)"),
        "energy_error": _num("work-energy balance E(t) - E(0) - W_torque(t) + W_damping(t), J: 0 for the exact "
                             "flow, the integrator's error otherwise (a tree scene: the whole tree's)"),
        "inputs": {
            "type": "object",
            "properties": {name: {"type": "number", "description": _INPUT_DESCRIPTIONS[name]}
                           for name in STATE_INPUTS},
            "additionalProperties": _NUM,
            "description": "inputs held over the last step (empty: the body has no input)",
        },
        "parent": {"type": "string", "description": "tree scenes: the parent frame, the parent body's name or "
                   "'world' for a root (the frame_id of the body's tf)"},
        "joint_type": {"type": "string", "description": "tree scenes: the joint to the parent: hinge, ball, "
                       "free_rotation, free or fixed"},
        "joint": {
            "type": "object",
            "properties": {name: {"type": "number", "description": f"{what}, {unit}"}
                           for name, (unit, what) in JOINT_VARIABLES.items()},
            "description": "tree scenes: the joint's variables (<body>.<name> in the model), those of its joint only",
        },
        "contacts": {
            "type": "array",
            "items": {
                "type": "object",
                "properties": {
                    "shape": {"type": "string", "description": "the shape (on this body)"},
                    "plane": {"type": "string", "description": "the plane it touches"},
                    "frame": {"type": "string", "description": "the contact point's tf frame (child of 'world', "
                              "in this body's tf): <body>/<shape>/contact, <body>/<shape>/<plane>/contact with "
                              "several planes"},
                    **{name: {"type": "number", "description": what + " (null when not finite)"}
                       for name, what in CONTACT_VALUES.items() if name != "mode"},
                    "mode": {"type": "integer", "description": CONTACT_VALUES["mode"],
                             "oneOf": [{"const": i, "title": m} for i, m in enumerate(CONTACT_MODES)]},
                },
            },
            "description": "scenes with contact: the contacts of this body's shapes, one per shape and plane (left "
                           "out for a body without shapes)",
        },
        "wall_ns": {"type": "integer", "description": "publisher wall clock at publication, ns since epoch "
                    "(beyond 2^53: JavaScript readers round it to about 0.2 us)"},
    },
    "required": ["t", "seq", "q", "omega"],
}

#: JSON Schema of a torque command.
TORQUE_JSON_SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": TORQUE_SCHEMA_NAME,
    "description": "Body-frame torque command, N*m, held until the next command.",
    "type": "object",
    "properties": {"x": {**_NUM, "description": "body x, N*m"}, "y": {**_NUM, "description": "body y, N*m"},
                   "z": {**_NUM, "description": "body z, N*m"}},
    "required": ["x", "y", "z"],
    "additionalProperties": False,
}

#: Foxglove's well-known schema name for one transform (drawn by its 3D panel).
FRAME_TRANSFORM_SCHEMA_NAME = "foxglove.FrameTransform"


def _xyz(*names: str, what: str) -> dict:
    return {"type": "object", "title": what, "properties": {n: _NUM for n in names}}


#: JSON Schema of ``foxglove.FrameTransform`` (as Foxglove's schemas repository publishes it for JSON).
FRAME_TRANSFORM_JSON_SCHEMA: dict = {
    "title": FRAME_TRANSFORM_SCHEMA_NAME,
    "description": "A transform between two reference frames in 3D space",
    "type": "object",
    "properties": {
        "timestamp": {"type": "object", "title": "time", "description": "Timestamp of transform",
                      "properties": {"sec": {"type": "integer", "minimum": 0},
                                     "nsec": {"type": "integer", "minimum": 0, "maximum": 999999999}}},
        "parent_frame_id": {"type": "string", "description": "Name of the parent frame"},
        "child_frame_id": {"type": "string", "description": "Name of the child frame"},
        "translation": {**_xyz("x", "y", "z", what="foxglove.Vector3"),
                        "description": "Translation component of the transform, m"},
        "rotation": {**_xyz("x", "y", "z", "w", what="foxglove.Quaternion"),
                     "description": "Rotation component of the transform"},
    },
}


# ----------------------------------------------------------------------------------------------- time
def seconds_to_ns(t: float) -> int:
    """Simulation time in s -> integer ns (rounded to nearest)."""
    return int(round(float(t) * 1e9))


def ns_to_stamp(ns: int) -> tuple[int, int]:
    """Integer ns -> ``(sec, nanosec)`` as in ``builtin_interfaces/Time`` (nanosec in [0, 1e9))."""
    sec, nanosec = divmod(int(ns), 1_000_000_000)
    return sec, nanosec


# ----------------------------------------------------------------------------------------------- state
def _finite_or_none(x) -> float | None:
    if x is None:
        return None
    x = float(x)
    return x if math.isfinite(x) else None


@dataclass(frozen=True)
class BodyState:
    """State of one body at simulation time ``t``, as published on ``.../state``.

    Parameters
    ----------
    t : float
        Simulation time, s.
    seq : int
        Per-body message counter (0, 1, 2, ...): gaps show lost messages.
    q : (4,) tuple of float
        Attitude quaternion ``(w, x, y, z)``, rotating body-frame vectors into the world frame.
    omega : (3,) tuple of float
        Body-frame angular velocity, rad/s.
    phi, theta, psi : float or None
        ZYZ Euler angles, rad.
    L : (3,) tuple of float or None
        World-frame angular momentum, kg*m^2/s.
    energy : float or None
        Total energy, J.
    energy_error : float or None
        Work-energy balance ``E(t) - E(0) - W_torque(t) + W_damping(t)``, J (0 for the exact flow).
    inputs : dict
        Inputs held over the last step (``tau_x``, ``tau_y``, ``tau_z``, ``motor_torque``, N*m).
    scene, body : str
        Names.
    wall_ns : int or None
        Publisher wall clock at publication (ns since the Unix epoch), for latency measurements.
    parent : str or None
        Tree scenes: the parent frame (the parent body's name, ``world`` for a root); None for a scene of
        independent bodies (then ``parent``, ``joint_type`` and ``joint`` are left out of the message).
    joint_type : str or None
        Tree scenes: ``hinge``, ``ball``, ``free_rotation``, ``free`` or ``fixed``.
    joint : dict
        Tree scenes: the joint variables by name (:data:`JOINT_VARIABLES`), those of the body's joint only.
    contacts : tuple of dict
        Scenes with contact: one dict per contact of the body's shapes, ``shape``, ``plane``, ``frame`` (the
        contact point's tf frame) and the values of :data:`CONTACT_VALUES`; empty (left out of the message) for a
        body without shapes.
    """

    t: float
    seq: int
    q: tuple
    omega: tuple
    phi: float | None = None
    theta: float | None = None
    psi: float | None = None
    L: tuple | None = None
    energy: float | None = None
    energy_error: float | None = None
    inputs: dict = field(default_factory=dict)
    scene: str = ""
    body: str = ""
    wall_ns: int | None = None
    parent: str | None = None
    joint_type: str | None = None
    joint: dict = field(default_factory=dict)
    contacts: tuple = ()

    @classmethod
    def from_outputs(cls, t: float, seq: int, outputs: dict, inputs: dict | None = None, *,
                     scene: str = "", body: str = "", wall_ns: int | None = None) -> BodyState:
        """Build from ``Model.outputs(body)`` and ``Model.inputs(body)`` dictionaries."""
        o = outputs
        L = None
        if all(k in o for k in ("L_x", "L_y", "L_z")):
            L = (float(o["L_x"]), float(o["L_y"]), float(o["L_z"]))
        return cls(
            t=float(t), seq=int(seq),
            q=(float(o["q_w"]), float(o["q_x"]), float(o["q_y"]), float(o["q_z"])),
            omega=(float(o["omega_x"]), float(o["omega_y"]), float(o["omega_z"])),
            phi=o.get("phi"), theta=o.get("theta"), psi=o.get("psi"), L=L, energy=o.get("energy"),
            energy_error=o.get("energy_error"),
            inputs={k: float(v) for k, v in (inputs or {}).items()},
            scene=scene, body=body, wall_ns=wall_ns,
        )

    @classmethod
    def from_tree_outputs(cls, t: float, seq: int, *, q_world, omega, parent: str, joint_type: str, joint: dict,
                          scene_outputs: dict, inputs: dict | None = None, scene: str = "", body: str = "",
                          wall_ns: int | None = None, contacts=()) -> BodyState:
        """Build the state of one body of a tree scene.

        Parameters
        ----------
        q_world : (4,) sequence of float
            The body's attitude in the world ``(w, x, y, z)`` (the model's ``<body>.q_world_*``).
        omega : (3,) sequence of float
            The body's angular velocity relative to the world in its own frame, rad/s.
        parent, joint_type : str
            The parent frame (``world`` for a root) and the joint's kind.
        joint : dict
            The joint variables by their short names (``angle``, ``rate``; ``q_w``.., ``omega_x``..).
        scene_outputs : dict
            The scene-wide outputs ``energy``, ``energy_error``, ``L_x``, ``L_y``, ``L_z`` (those present are used).
        inputs : dict, optional
            The body's inputs by their short names (``motor_torque``, ``tau_x``..).
        contacts : iterable of dict, optional
            The contacts of the body's shapes: ``shape``, ``plane``, ``frame`` and :data:`CONTACT_VALUES`.
        """
        o = scene_outputs
        L = None
        if all(k in o for k in ("L_x", "L_y", "L_z")):
            L = (float(o["L_x"]), float(o["L_y"]), float(o["L_z"]))
        return cls(
            t=float(t), seq=int(seq), q=tuple(float(v) for v in q_world), omega=tuple(float(v) for v in omega),
            L=L, energy=o.get("energy"), energy_error=o.get("energy_error"),
            inputs={k: float(v) for k, v in (inputs or {}).items()}, scene=scene, body=body, wall_ns=wall_ns,
            parent=str(parent), joint_type=str(joint_type), joint={k: float(v) for k, v in joint.items()},
            contacts=tuple(dict(c) for c in contacts),
        )

    def to_dict(self) -> dict:
        """JSON-ready dictionary (non-finite numbers become null)."""
        d = {
            "t": self.t, "seq": self.seq, "scene": self.scene, "body": self.body,
            "q": list(self.q), "omega": list(self.omega),
            "phi": _finite_or_none(self.phi), "theta": _finite_or_none(self.theta),
            "psi": _finite_or_none(self.psi),
            "L": None if self.L is None else [_finite_or_none(v) for v in self.L],
            "energy": _finite_or_none(self.energy),
            "energy_error": _finite_or_none(self.energy_error),
            "inputs": {k: v for k, v in self.inputs.items() if math.isfinite(v)},
        }
        if self.wall_ns is not None:
            d["wall_ns"] = int(self.wall_ns)
        if self.parent is not None:  # a tree body: no ZYZ angles of its own; its joint instead
            for k in ("phi", "theta", "psi"):
                if d[k] is None:
                    del d[k]
            d["parent"] = self.parent
            d["joint_type"] = self.joint_type or ""
            d["joint"] = {k: _finite_or_none(v) for k, v in self.joint.items()}
        if self.contacts:
            d["contacts"] = [_contact_dict(c) for c in self.contacts]
        return d


def _contact_dict(c: dict) -> dict:
    """One contact of a BodyState as JSON: names as strings, values finite or null, ``mode`` an integer."""
    out = {k: str(c[k]) for k in ("shape", "plane", "frame") if k in c}
    for k in CONTACT_VALUES:
        v = _finite_or_none(c.get(k))
        out[k] = (None if v is None else int(round(v))) if k == "mode" else v
    return out


def encode_state(state: BodyState) -> bytes:
    """BodyState -> UTF-8 JSON bytes (compact)."""
    return json.dumps(state.to_dict(), separators=(",", ":"), allow_nan=False).encode()


def decode_state(data: bytes | str) -> dict:
    """UTF-8 JSON BodyState -> dict (keys as in :data:`BODY_STATE_JSON_SCHEMA`)."""
    return json.loads(data)


# ------------------------------------------------------------------------------------------------- CDR
@cache
def _encoder(type_name: str):
    from mcap_ros2._dynamic import serialize_dynamic

    return serialize_dynamic(type_name, _MSGDEFS[type_name])[type_name]


@cache
def _decoder(type_name: str, msgdef: str):
    from mcap_ros2._dynamic import generate_dynamic

    return generate_dynamic(type_name, msgdef)[type_name]


def _header(t: float, frame_id: str) -> dict:
    sec, nanosec = ns_to_stamp(seconds_to_ns(t))
    return {"stamp": {"sec": sec, "nanosec": nanosec}, "frame_id": frame_id}


def _quat_xyzw(q) -> dict:
    w, x, y, z = (float(v) for v in q)
    return {"x": x, "y": y, "z": z, "w": w}


def encode_tf(t: float, q, *, child_frame_id: str, frame_id: str = WORLD_FRAME,
              translation=(0.0, 0.0, 0.0)) -> bytes:
    """CDR ``tf2_msgs/msg/TFMessage`` with one transform ``frame_id -> child_frame_id``.

    Parameters
    ----------
    t : float
        Simulation time, s (header stamp).
    q : (4,) array_like
        Rotation ``(w, x, y, z)`` of the child frame relative to the parent frame (rotating child-frame vectors
        into the parent frame): the body's attitude for a body whose parent is the world.
    child_frame_id : str
        The body's frame (the body name).
    frame_id : str
        Parent frame, default ``world`` (a tree body: its parent body's name, ``world`` for a root).
    translation : (3,) array_like
        Position of the body frame's origin in the parent frame, m (the pivot, or the centre of mass of a free
        body; a tree body: its joint point, plus the position ``r`` of a free joint).
    """
    return encode_tf_frames(t, [(child_frame_id, frame_id, q, translation)])


def encode_tf_frames(t: float, frames) -> bytes:
    """CDR ``tf2_msgs/msg/TFMessage`` with one transform per ``(child_frame_id, frame_id, q, translation)`` of
    ``frames`` (as :func:`encode_tf`'s arguments): every body's frame in one message, as ROS 2's ``/tf`` has it."""
    transforms = []
    for child, parent, q, translation in frames:
        tx, ty, tz = (float(v) for v in translation)
        transforms.append({"header": _header(t, parent), "child_frame_id": child,
                           "transform": {"translation": {"x": tx, "y": ty, "z": tz}, "rotation": _quat_xyzw(q)}})
    return bytes(_encoder(TF_TYPE)({"transforms": transforms}))


def encode_clock(t: float) -> bytes:
    """CDR ``rosgraph_msgs/msg/Clock`` at simulation time ``t`` (s)."""
    sec, nanosec = ns_to_stamp(seconds_to_ns(t))
    return bytes(_encoder(CLOCK_TYPE)({"clock": {"sec": sec, "nanosec": nanosec}}))


def encode_joint_state(t: float, names, positions, velocities) -> bytes:
    """CDR ``sensor_msgs/msg/JointState``: the hinge joints ``names`` at their angles (rad) and rates (rad/s); no
    effort (an empty array, as ROS allows)."""
    return bytes(_encoder(JOINT_STATE_TYPE)({
        "header": _header(t, ""), "name": list(names), "position": [float(v) for v in positions],
        "velocity": [float(v) for v in velocities], "effort": []}))


_UNKNOWN_COV = [0.0] * 9
_NOT_PROVIDED_COV = [-1.0] + [0.0] * 8


def encode_imu(t: float, q, omega_body, *, frame_id: str, linear_acceleration=None) -> bytes:
    """CDR ``sensor_msgs/msg/Imu``: orientation, body-frame angular velocity and linear acceleration.

    The simulation gives them exactly, so their covariances are all zeros ("unknown" in ROS terms, no estimate of
    error). ``linear_acceleration`` is the specific force at the body's origin in its frame, as a real IMU reads it
    (``Model.specific_force``: a body at rest on a support reads +g along the world's up); without it the message
    says "not provided" (covariance element 0 is -1, as ROS asks).

    Parameters
    ----------
    t : float
        Simulation time, s (header stamp).
    q : (4,) array_like
        Attitude ``(w, x, y, z)``, body -> world.
    omega_body : (3,) array_like
        Body-frame angular velocity, rad/s.
    frame_id : str
        The body's frame (the body name).
    linear_acceleration : (3,) array_like, optional
        Specific force a - g at the body's origin, body frame, m/s^2.
    """
    wx, wy, wz = (float(v) for v in omega_body)
    ax, ay, az = (0.0, 0.0, 0.0) if linear_acceleration is None else (float(v) for v in linear_acceleration)
    msg = {
        "header": _header(t, frame_id),
        "orientation": _quat_xyzw(q),
        "orientation_covariance": _UNKNOWN_COV,
        "angular_velocity": {"x": wx, "y": wy, "z": wz},
        "angular_velocity_covariance": _UNKNOWN_COV,
        "linear_acceleration": {"x": ax, "y": ay, "z": az},
        "linear_acceleration_covariance": _NOT_PROVIDED_COV if linear_acceleration is None else _UNKNOWN_COV,
    }
    return bytes(_encoder(IMU_TYPE)(msg))


def encode_frame_transform(t: float, q, *, child_frame_id: str, parent_frame_id: str = WORLD_FRAME,
                           translation=(0.0, 0.0, 0.0)) -> bytes:
    """JSON ``foxglove.FrameTransform`` (the Foxglove live view's transform; :data:`FRAME_TRANSFORM_JSON_SCHEMA`).

    The same transform as :func:`encode_tf`: ``parent_frame_id`` -> ``child_frame_id`` at simulation time ``t``
    (s), rotation ``q = (w, x, y, z)`` child -> parent, translation in m (in the parent frame).

    Examples
    --------
    >>> json.loads(encode_frame_transform(1.5, (1, 0, 0, 0), child_frame_id="gyro"))["timestamp"]
    {'sec': 1, 'nsec': 500000000}
    """
    sec, nsec = ns_to_stamp(seconds_to_ns(t))
    tx, ty, tz = (float(v) for v in translation)
    d = {"timestamp": {"sec": sec, "nsec": nsec}, "parent_frame_id": parent_frame_id,
         "child_frame_id": child_frame_id, "translation": {"x": tx, "y": ty, "z": tz},
         "rotation": _quat_xyzw(q)}
    return json.dumps(d, separators=(",", ":"), allow_nan=False).encode()


def decode_cdr(type_name: str, data: bytes, msgdef: str | None = None) -> Any:
    """Decode a CDR payload with ``mcap-ros2-support``'s dynamic decoder.

    Parameters
    ----------
    type_name : str
        ROS 2 type, e.g. ``sensor_msgs/msg/Imu``.
    data : bytes
        Payload with its 4-byte encapsulation header.
    msgdef : str, optional
        Concatenated definition; default: the one this module publishes.
    """
    return _decoder(type_name, msgdef if msgdef is not None else _MSGDEFS[type_name])(data)


# ---------------------------------------------------------------------------------------------- torque
@dataclass(frozen=True)
class Torque:
    """Body-frame torque command, N*m."""

    x: float
    y: float
    z: float

    def as_inputs(self) -> dict[str, float]:
        """As model inputs ``tau_x, tau_y, tau_z``."""
        return {"tau_x": self.x, "tau_y": self.y, "tau_z": self.z}


class TorqueRejected(ConfigError):
    """A torque command that is not accepted; ``reason`` says why in one line."""

    def __init__(self, reason: str, value=None):
        self.reason = reason
        super().__init__("torque", value, reason)

    def __str__(self) -> str:
        return f"torque command rejected: {self.reason}"


#: Largest accepted torque payload, bytes.
MAX_TORQUE_PAYLOAD = 1024


def _parse_object(payload, members: tuple[str, ...], reject, expected: str, unit: str = "N*m") -> dict:
    """Decode a command payload to a JSON object with exactly ``members`` (checks as :func:`parse_torque`)."""
    if isinstance(payload, str):
        text = payload
        if len(text) > MAX_TORQUE_PAYLOAD:
            raise reject(f"payload of {len(text)} characters, at most {MAX_TORQUE_PAYLOAD} allowed")
    else:
        raw = bytes(payload)
        if len(raw) > MAX_TORQUE_PAYLOAD:
            raise reject(f"payload of {len(raw)} bytes, at most {MAX_TORQUE_PAYLOAD} allowed")
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as e:
            raise reject(f"payload is not UTF-8 ({e.reason} at byte {e.start})", raw[:40]) from None

    def _reject_constant(name):  # json accepts NaN/Infinity literals by default: reject them by name
        raise ValueError(f"{name} is not a finite number")

    try:
        obj = json.loads(text, parse_constant=_reject_constant)
    except ValueError as e:
        raise reject(f"not valid JSON ({e})", text[:80]) from None
    if not isinstance(obj, dict):
        raise reject(f"expected a JSON object {expected}, got {type(obj).__name__}", obj)
    missing = [k for k in members if k not in obj]
    if missing:
        raise reject(f"missing member(s) {', '.join(missing)}; expected {', '.join(members)} in {unit}", obj)
    extra = sorted(set(obj) - set(members))
    if extra:
        raise reject(f"unknown member(s) {', '.join(extra)}; expected only {', '.join(members)}", obj)
    return obj


def _torque_value(obj: dict, k: str, limit: float, reject, unit: str = "N*m") -> float:
    v = obj[k]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise reject(f"{k} = {v!r} is a {type(v).__name__}, expected a number ({unit})", obj)
    try:
        v = float(v)
    except OverflowError:  # a JSON integer beyond the float range
        raise reject(f"{k} is an integer of {len(str(obj[k]))} digits, not a finite float",
                     "<huge integer>") from None
    if not math.isfinite(v):
        raise reject(f"{k} = {obj[k]!r} is not finite", obj)
    if abs(v) > limit:
        raise reject(f"|{k}| = {abs(v):g} {unit} exceeds the limit {limit:g} {unit}", obj)
    return v


def parse_torque(payload: bytes | bytearray | memoryview | str,
                 limit: float = DEFAULT_TORQUE_LIMIT) -> Torque:
    """Parse and validate a torque command ``{"x": .., "y": .., "z": ..}`` (N*m, body frame).

    Parameters
    ----------
    payload : bytes or str
        UTF-8 JSON object with exactly the numeric members ``x``, ``y``, ``z``.
    limit : float
        Largest accepted absolute value of each component, N*m.

    Returns
    -------
    Torque

    Raises
    ------
    TorqueRejected
        With ``reason`` naming what is wrong: too long, not UTF-8, not JSON, not an object, missing or unknown
        members, a member that is not a number (booleans included), NaN or infinite, or beyond ``limit``.
    """
    obj = _parse_object(payload, ("x", "y", "z"), TorqueRejected, '{"x", "y", "z"}')
    return Torque(*(_torque_value(obj, k, limit, TorqueRejected) for k in ("x", "y", "z")))


@dataclass(frozen=True)
class MotorTorque:
    """Hinge motor torque command, N*m about the joint axis (on the body; its reaction on the parent)."""

    torque: float

    def as_inputs(self) -> dict[str, float]:
        """As the model input ``motor_torque``."""
        return {"motor_torque": self.torque}


class MotorRejected(TorqueRejected):
    """A motor command that is not accepted; ``reason`` says why in one line."""

    def __str__(self) -> str:
        return f"motor command rejected: {self.reason}"


#: JSON Schema of a motor command.
MOTOR_JSON_SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": MOTOR_SCHEMA_NAME,
    "description": "Hinge motor torque command about the joint axis, N*m (on the body; its reaction on the "
                   "parent), held until the next command.",
    "type": "object",
    "properties": {"torque": {**_NUM, "description": "motor torque about the hinge axis, N*m"}},
    "required": ["torque"],
    "additionalProperties": False,
}


def parse_motor(payload: bytes | bytearray | memoryview | str,
                limit: float = DEFAULT_TORQUE_LIMIT) -> MotorTorque:
    """Parse and validate a motor command ``{"torque": ..}`` (N*m about the hinge axis).

    Parameters
    ----------
    payload : bytes or str
        UTF-8 JSON object with exactly the numeric member ``torque``.
    limit : float
        Largest accepted absolute value, N*m.

    Raises
    ------
    MotorRejected
        As :func:`parse_torque` rejects a torque command.
    """
    obj = _parse_object(payload, ("torque",), MotorRejected, '{"torque"}')
    return MotorTorque(_torque_value(obj, "torque", limit, MotorRejected))


@dataclass(frozen=True)
class MotorForce:
    """A slider's motor force command, N along the joint axis (on the body; its reaction on the parent)."""

    force: float

    def as_inputs(self) -> dict[str, float]:
        """As the model input ``motor_force``."""
        return {"motor_force": self.force}


#: JSON Schema of a slider's motor command.
MOTOR_FORCE_JSON_SCHEMA: dict = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": MOTOR_FORCE_SCHEMA_NAME,
    "description": "Slider motor force command along the joint axis, N (on the body; its reaction on the parent), "
                   "held until the next command.",
    "type": "object",
    "properties": {"force": {**_NUM, "description": "motor force along the slider axis, N"}},
    "required": ["force"],
    "additionalProperties": False,
}


def parse_motor_force(payload: bytes | bytearray | memoryview | str,
                      limit: float = DEFAULT_FORCE_LIMIT) -> MotorForce:
    """Parse and validate a slider's motor command ``{"force": ..}`` (N along the axis), with the checks of
    :func:`parse_motor` (size, UTF-8, JSON, exactly the one finite numeric member, ``|force| <= limit``).

    Raises
    ------
    MotorRejected
        With ``reason`` naming what is wrong.
    """
    obj = _parse_object(payload, ("force",), MotorRejected, '{"force"} (N along the slider\'s axis)', "N")
    return MotorForce(_torque_value(obj, "force", limit, MotorRejected, "N"))


def encode_motor_force(force: float) -> bytes:
    """A slider's motor command payload ``{"force"}`` (N along the axis)."""
    return json.dumps({"force": float(force)}, allow_nan=True).encode()


def encode_motor(torque: float) -> bytes:
    """Motor command payload ``{"torque"}`` (N*m about the hinge axis)."""
    return json.dumps({"torque": float(torque)}, allow_nan=True).encode()


def encode_torque(x: float, y: float, z: float) -> bytes:
    """Torque command payload ``{"x", "y", "z"}`` (N*m, body frame)."""
    return json.dumps({"x": float(x), "y": float(y), "z": float(z)}, allow_nan=True).encode()


def encode_params(info: dict) -> bytes:
    """JSON reply of a ``.../params`` query (non-finite numbers become null)."""

    def clean(v):
        if isinstance(v, float) and not math.isfinite(v):
            return None
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items()}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    return json.dumps(clean(info), separators=(",", ":"), allow_nan=False).encode()


# ------------------------------------------------------------------------------------- times of payloads
_STAMP = struct.Struct("<iI")


def sim_time_ns(encoding: str, payload: bytes) -> int | None:
    """Simulation time (ns) carried by a payload, or None if its encoding carries none or it is malformed.

    BodyState: ``t``; Imu: header stamp; TFMessage: stamp of the first transform.
    """
    encoding = str(encoding)
    try:
        if encoding == STATE_ENCODING:
            return seconds_to_ns(json.loads(payload)["t"])
        if encoding == IMU_ENCODING:  # encapsulation (4) | header.stamp
            sec, nanosec = _STAMP.unpack_from(payload, 4)
            return sec * 1_000_000_000 + nanosec
        if encoding == TF_ENCODING:  # encapsulation (4) | sequence length (4) | transforms[0].header.stamp
            (n,) = struct.unpack_from("<I", payload, 4)
            if n == 0:
                return None
            sec, nanosec = _STAMP.unpack_from(payload, 8)
            return sec * 1_000_000_000 + nanosec
    except (ValueError, KeyError, TypeError, struct.error):
        return None
    return None


def stamp_and_seq(encoding: str, payload: bytes) -> tuple[int | None, int | None]:
    """``(simulation time ns, sequence number)`` of a payload; None where it carries none.

    Only BodyState carries a sequence number (``seq``); the time is as in :func:`sim_time_ns`.
    """
    if str(encoding) == STATE_ENCODING:
        try:
            d = json.loads(payload)
            seq = d.get("seq")
            return seconds_to_ns(d["t"]), seq if isinstance(seq, int) and seq >= 0 else None
        except (ValueError, KeyError, TypeError, AttributeError):
            return None, None
    return sim_time_ns(encoding, payload), None


# ----------------------------------------------------------------------------------------- MCAP schemas
@dataclass(frozen=True)
class ChannelSchema:
    """How a Zenoh encoding maps to an MCAP channel.

    Attributes
    ----------
    message_encoding : str
        MCAP message encoding (``json``, ``cdr``, ...).
    name : str
        Schema name; empty when there is no schema.
    encoding : str
        Schema encoding (``jsonschema``, ``ros2msg``); empty when there is no schema.
    data : bytes
        Schema data.
    """

    message_encoding: str
    name: str = ""
    encoding: str = ""
    data: bytes = b""


_MESSAGE_ENCODINGS = {
    "application/json": "json",
    "text/json": "json",
    "application/cdr": "cdr",
    "application/cbor": "cbor",
    "application/protobuf": "protobuf",
    "application/msgpack": "msgpack",
    "application/flatbuffers": "flatbuffer",
}


def _json_schema_bytes(schema: dict) -> bytes:
    return json.dumps(schema, indent=1).encode()


def schema_for_encoding(zenoh_encoding: str, key: str | None = None) -> ChannelSchema:
    """MCAP channel description for a Zenoh encoding string (and, optionally, the key it came on).

    Known gyrosim encodings get their full schema (a JSON key ending in ``/torque`` gets the torque schema, one
    ending in ``/motor`` the motor schema);
    other ``application/json`` keys get a schema-less ``json`` channel; other encodings keep the Zenoh
    encoding string as message encoding (the bytes are kept verbatim).

    Examples
    --------
    >>> schema_for_encoding(IMU_ENCODING).name
    'sensor_msgs/msg/Imu'
    >>> schema_for_encoding("zenoh/bytes").message_encoding
    'zenoh/bytes'
    """
    enc = str(zenoh_encoding)
    base, _, schema = enc.partition(";")
    if enc == STATE_ENCODING:
        return ChannelSchema("json", STATE_SCHEMA_NAME, "jsonschema",
                             _json_schema_bytes(BODY_STATE_JSON_SCHEMA))
    if base == "application/cdr" and schema in _MSGDEFS:
        return ChannelSchema("cdr", schema, "ros2msg", _MSGDEFS[schema].encode())
    if enc == TORQUE_ENCODING and key is not None and str(key).endswith("/torque"):
        return ChannelSchema("json", TORQUE_SCHEMA_NAME, "jsonschema", _json_schema_bytes(TORQUE_JSON_SCHEMA))
    if enc == MOTOR_ENCODING and key is not None and str(key).endswith("/motor"):
        return ChannelSchema("json", MOTOR_SCHEMA_NAME, "jsonschema", _json_schema_bytes(MOTOR_JSON_SCHEMA))
    if enc == MOTOR_FORCE_ENCODING:
        return ChannelSchema("json", MOTOR_FORCE_SCHEMA_NAME, "jsonschema",
                             _json_schema_bytes(MOTOR_FORCE_JSON_SCHEMA))
    if base in _MESSAGE_ENCODINGS:
        return ChannelSchema(_MESSAGE_ENCODINGS[base])
    return ChannelSchema(enc)


def encoding_for_channel(message_encoding: str, schema_name: str | None, metadata: dict | None = None) -> str:
    """Zenoh encoding to republish an MCAP channel with (replay).

    The channel metadata entry ``zenoh_encoding`` written by the recorder wins; otherwise it is rebuilt from
    the message encoding and schema name.
    """
    if metadata and metadata.get("zenoh_encoding"):
        return metadata["zenoh_encoding"]
    inverse = {v: k for k, v in _MESSAGE_ENCODINGS.items() if k != "text/json"}
    base = inverse.get(message_encoding, message_encoding)
    return f"{base};{schema_name}" if schema_name else base
