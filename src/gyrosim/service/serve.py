"""``gyrosim serve``: step a scene's model in real time and publish it on Zenoh.

Reads like Zenoh's examples: :func:`main` takes a ``zenoh.Config`` and runs ``with zenoh.open(config) as
session``. For every body of the scene it publishes, after each communication step of ``1 / rate`` s,

* ``<prefix>/<scene>/<body>/state`` JSON BodyState, ``.../tf`` CDR TFMessage, ``.../imu`` CDR Imu
  (reliable, ``CongestionControl.BLOCK``: a slow subscriber slows the service down instead of losing data),

subscribes ``.../torque`` (``{"x", "y", "z"}`` N*m, body frame, held until the next command) on the bodies with
torque inputs and ``.../motor`` on the bodies with a joint motor (``{"torque": x}`` N*m about a hinge's axis,
``{"force": x}`` N along a slider's axis, held likewise; malformed or out-of-limit commands, and a torque sent to a
slider or a force to a hinge, are logged, counted and ignored; a body without such an input has no such
subscriber), answers ``.../params`` queries with the current parameters, inputs and counters, and holds the
liveliness token ``<prefix>/<scene>/alive``. Zenoh's callbacks only queue (``FifoChannel``); all work happens in
the stepping thread.

Tree scenes (bodies joined by joints, docs/trees.md): every body's ``tf`` is the transform from its
parent frame (``frame_id`` the parent body's name, ``world`` for a root; translation the joint point, rotation
the joint's), its ``state`` carries its world attitude ``q``, its angular velocity, its joint variables
(``joint``) and the scene-wide energy and angular momentum, its ``imu`` the world attitude and angular velocity
(:mod:`gyrosim.service.tree`).

Scenes with contact (``[[shape]]`` and ``[[plane]]`` tables): every contact (a shape against a plane) is a tf frame
too, in the ``tf`` of the body that carries the shape (the same TFMessage, after the body's own transform; on
ROS 2's ``/tf`` and the Foxglove live view likewise): ``world`` -> ``<body>/<shape>/contact`` (with several planes
``<body>/<shape>/<plane>/contact``), translation the contact point (the model's ``<shape>.contact_x..z``, world, m),
rotation the plane's normal as the frame's z (the identity for a floor of normal +z), the stamp the body frames'.
It is published at every step, also while the shape is apart from the plane (then the point is the shape's point
nearest the plane). The body's ``state`` carries the contacts' gap, normal force, slip speed and mode
(``contacts``).

With ``foxglove`` set, a Foxglove WebSocket server (:mod:`gyrosim.service.live`) streams the same channels
for a live view in Foxglove.

Time-varying inputs from a file (``input_file``, ``gyrosim serve SCENE --input-file FILE.csv``): FMPy's CSV format
(a ``time`` column, one column per input: ``tau_x``.. for a one-body scene, ``<body>.tau_x``.. for several
bodies, ``<body>.motor_torque``, ``<body>.motor_force`` and ``<body>.tau_x``.. for a tree scene;
:mod:`gyrosim.inputs`), checked against
the scene before anything starts. Before every communication step the file's values at the step's start time
(simulation time; linear between rows, held after the last row, as FMPy applies them) are set and held over the
step. A Zenoh command (``.../torque``, ``.../motor``) replaces the file's value of the inputs it sets until the
simulation time reaches the file's next row; from then on the file applies again (after the last row a
command holds until the next command).

Pacing: simulated time runs ``realtime_factor`` times as fast as the wall clock (1: real time; 0: as fast as
possible). A step that falls behind is not skipped (every step is published); the lag is reported.
"""

from __future__ import annotations

import logging
import math
import signal
import threading
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass

from ..errors import ConfigError, GyrosimError, IntegrationError, StepError
from ..telemetry import messages as msg
from . import keys as K
from .config import describe_endpoints, open_session, zenoh_error
from .ros2 import Frame
from .tree import CONTACT_STATE, SCENE_OUTPUTS, FrameState, TreeFrames

__all__ = ["ServeOptions", "ServeStats", "Service", "main", "build_model", "install_stop_signals", "MOTOR_INPUTS"]

log = logging.getLogger("gyrosim.service")

#: A joint motor's input by its short name -> (the member of its ``.../motor`` command, unit, the joint).
MOTOR_INPUTS = {"motor_torque": ("torque", "N*m", "hinge"), "motor_force": ("force", "N", "slider")}


@dataclass(frozen=True)
class ServeOptions:
    """Options of :func:`main` (the ``gyrosim serve`` flags).

    Parameters
    ----------
    rate : float
        Publication rate = communication steps per simulated second, Hz (> 0).
    realtime_factor : float
        Simulated seconds per wall-clock second; 0 runs as fast as possible.
    duration : float or None
        Simulated seconds to run; None runs until SIGINT/SIGTERM (or ``wall_duration``).
    wall_duration : float or None
        Wall-clock seconds to run at most; None: no wall-clock limit.
    record : str or None
        MCAP file to record everything published (and accepted torque commands) into.
    prefix : str
        First key chunk(s).
    torque_limit : float
        Largest accepted |torque component| (and |hinge motor torque|), N*m.
    force_limit : float
        Largest accepted |slider motor force|, N.
    wait_subscribers : float
        Wait up to this many wall seconds for a subscriber on every state key before stepping.
    linger : float
        Wall seconds to keep the session open after the last message, so queued messages leave.
    foxglove : tuple (host, port) or None
        Also run a Foxglove WebSocket server there (port 0: a free port).
    input_file : str or None
        CSV file of time-varying inputs in FMPy's format (see the module's notes).
    ros_domain : int or None
        Also be a ROS 2 node in rmw_zenoh's protocol on this ROS domain (:mod:`gyrosim.service.ros2`); None: not.
    ros_distro : str
        rmw_zenoh's wire protocol: ``jazzy`` (also Kilted, Rolling) or ``humble``.
    """

    rate: float = 100.0
    realtime_factor: float = 1.0
    duration: float | None = None
    record: str | None = None
    prefix: str = K.DEFAULT_PREFIX
    torque_limit: float = msg.DEFAULT_TORQUE_LIMIT
    wait_subscribers: float = 0.0
    linger: float = 0.2
    wall_duration: float | None = None
    foxglove: tuple | None = None
    input_file: str | None = None
    ros_domain: int | None = None
    ros_distro: str = "jazzy"
    force_limit: float = msg.DEFAULT_FORCE_LIMIT

    def __post_init__(self):
        if not (isinstance(self.rate, (int, float)) and math.isfinite(self.rate) and self.rate > 0):
            raise ConfigError("rate", self.rate, "a finite rate > 0 Hz")
        if not (math.isfinite(self.realtime_factor) and self.realtime_factor >= 0):
            raise ConfigError("realtime_factor", self.realtime_factor,
                              "a finite factor >= 0 (0: as fast as possible)")
        if self.duration is not None and not (math.isfinite(self.duration) and self.duration > 0):
            raise ConfigError("duration", self.duration, "a finite number of simulated seconds > 0")
        if self.wall_duration is not None and not (math.isfinite(self.wall_duration) and self.wall_duration > 0):
            raise ConfigError("wall_duration", self.wall_duration, "a finite number of wall seconds > 0")
        if not (math.isfinite(self.torque_limit) and self.torque_limit > 0):
            raise ConfigError("torque_limit", self.torque_limit, "a finite limit > 0 N*m")
        if not (isinstance(self.force_limit, (int, float)) and math.isfinite(self.force_limit)
                and self.force_limit > 0):
            raise ConfigError("force_limit", self.force_limit, "a finite limit > 0 N")
        if not (math.isfinite(self.wait_subscribers) and self.wait_subscribers >= 0):
            raise ConfigError("wait_subscribers", self.wait_subscribers, "seconds >= 0")


@dataclass
class ServeStats:
    """Counters of a service run."""

    steps: int = 0
    published: int = 0
    torque_accepted: int = 0
    torque_rejected: int = 0
    motor_accepted: int = 0
    motor_rejected: int = 0
    last_rejection: str | None = None
    queries: int = 0
    sim_time: float = 0.0
    wall_time: float = 0.0
    max_lag: float = 0.0
    stopped_by: str = ""
    recorded: int = 0
    #: ``--record`` got no message (the service stopped before it published): the file was not written
    record_empty: bool = False

    def format(self) -> str:
        rate = self.steps / self.wall_time if self.wall_time > 0 else float("nan")
        s = (f"served {self.steps} steps ({self.sim_time:.3f} s simulated in {self.wall_time:.3f} s wall, "
             f"{rate:.1f} steps/s), published {self.published} messages, torque commands: "
             f"{self.torque_accepted} accepted, {self.torque_rejected} rejected; "
             f"{self.queries} params queries; largest lag behind schedule {self.max_lag * 1e3:.1f} ms")
        if self.motor_accepted or self.motor_rejected:
            s += f"; motor commands: {self.motor_accepted} accepted, {self.motor_rejected} rejected"
        if self.recorded:
            s += f"; recorded {self.recorded} messages"
        if self.stopped_by:
            s += f"; stopped by {self.stopped_by}"
        return s


class _FileInputs:
    """An input file applied at the service's step times; Zenoh commands override it until the file's next row."""

    def __init__(self, signal, model, bodies: list[str]):
        self.signal = signal
        self.model = model
        self.setters = []  # (variable, body argument of model.set, (body index, short name), column)
        for j, (name, var, body) in enumerate(signal.check_against(model)):
            b, short = model.scene.split_name(name)  # -1: an input every body of a one-body scene takes
            where = (-1 if b is None else b, short)
            self.setters.append((var, body, where, j))
        self.times = [float(x) for x in signal.time]
        self.overrides: dict[tuple[int, str], int] = {}  # (body, input) -> the file row when the command came

    def row(self, t: float) -> int:
        """Index of the file's last row at or before ``t`` (-1 before the first; rows at ``t`` within FMPy's
        tolerance count as reached)."""
        import bisect

        tt = self.times
        i = bisect.bisect_right(tt, t)
        while i < len(tt) and math.isclose(t, tt[i]):
            i += 1
        return i - 1

    def overridden(self, body: int, inputs: dict, t: float) -> None:
        row = self.row(t)
        for name in inputs:
            self.overrides[(body, name)] = row

    def apply(self, t: float) -> None:
        row = self.row(t)
        if self.overrides:  # a command holds until the file's next row is reached
            self.overrides = {k: r for k, r in self.overrides.items() if r >= row}
        values = self.signal.row_at(t)
        for var, body, where, j in self.setters:
            if where not in self.overrides:
                self.model.set(var, values[j], body=body)


def build_model(scene=None, parameters: dict | None = None):
    """Build the :class:`gyrosim.model.Model` the service steps (no stop time: it runs until stopped)."""
    from ..model import Model

    return Model(scene, parameters=dict(parameters or {}), stop_time=None)


def install_stop_signals(stop: threading.Event, stats: ServeStats | None = None) -> Callable[[], None]:
    """Make SIGINT and SIGTERM set ``stop`` (main thread only); return a function restoring the handlers."""
    if threading.current_thread() is not threading.main_thread():
        return lambda: None
    old = {}

    def handler(signum, frame):
        if stats is not None and not stats.stopped_by:
            stats.stopped_by = signal.Signals(signum).name
        if stop.is_set():  # second signal: give up on a clean stop
            raise KeyboardInterrupt
        stop.set()

    for sig in (signal.SIGINT, signal.SIGTERM):
        old[sig] = signal.signal(sig, handler)

    def restore():
        for sig, h in old.items():
            signal.signal(sig, h)

    return restore


class Service:
    """The publishers, subscribers, queryables and token of one model on one session.

    Parameters
    ----------
    session : zenoh.Session
        Open session.
    model : gyrosim.model.Model
        The model to step (its scene name and body names make the keys).
    options : ServeOptions
        Rate, pacing, limits.
    recorder : gyrosim.telemetry.recorder.Recorder, optional
        Records every published message and every accepted torque command.
    live : gyrosim.service.live.LiveView, optional
        Foxglove WebSocket server that gets every published message too.
    inputs : gyrosim.inputs.InputSignal, optional
        Time-varying inputs applied before every step (see the module's notes); checked against the model.
    """

    def __init__(self, session, model, options: ServeOptions = ServeOptions(), recorder=None, live=None,
                 inputs=None):
        import zenoh

        self.session = session
        self.model = model
        self.options = options
        self.recorder = recorder
        self.live = live
        self.stats = ServeStats()
        self.scene = model.scene.name
        self.bodies = list(model.body_names)
        self.keys = [K.BodyKeys(self.scene, b, options.prefix) for b in self.bodies]
        self.h = 1.0 / options.rate
        self._seq = [0] * len(self.bodies)
        self.tree = None
        if model.scene.kernel == "tree":  # each body from its parent's frame; inputs named <body>.<name>
            self.tree = TreeFrames(model)
            # a tree model's inputs are named <body>.<name>: each body's own, by their short names
            names = [n for n, v in model.variables.items() if v.causality == "input"]
            split = [model.scene.split_name(n) for n in names]
            self._input_names = [[(short, n) for n, (b, short) in zip(names, split) if b == i]
                                 for i in range(len(self.bodies))]
        else:
            self._input_names = None
        #: body index -> its shapes' contacts (gyrosim.service.tree.ContactFrame), published with its tf and state
        self._contacts = [[c for c in (self.tree.contacts if self.tree is not None else ()) if c.body_index == i]
                          for i in range(len(self.bodies))]
        self._file = _FileInputs(inputs, model, self.bodies) if inputs is not None else None
        self._torque_bodies = [i for i in range(len(self.bodies)) if "tau_x" in self.body_inputs(i)]
        #: body index -> its joint motor's input (motor_torque of a hinge, motor_force of a slider)
        self._motors = {}
        for i in range(len(self.bodies)):
            motor = next((n for n in MOTOR_INPUTS if n in self.body_inputs(i)), None)
            if motor is not None:
                self._motors[i] = motor
        self._motor_bodies = list(self._motors)
        self._rejections_logged = 0

        def pub(key, encoding):
            return session.declare_publisher(key, encoding=zenoh.Encoding(encoding),
                                             congestion_control=zenoh.CongestionControl.BLOCK,
                                             reliability=zenoh.Reliability.RELIABLE)

        self.publishers = [
            {"state": pub(k.state, msg.STATE_ENCODING), "tf": pub(k.tf, msg.TF_ENCODING),
             "imu": pub(k.imu, msg.IMU_ENCODING)}
            for k in self.keys
        ]
        # a body has the subscribers of the inputs it has: a publisher's matching status says whether its commands
        # are taken (params queries list every body's inputs)
        self.torque_subs = {i: session.declare_subscriber(self.keys[i].torque, zenoh.handlers.FifoChannel(1024))
                            for i in self._torque_bodies}
        self.motor_subs = {i: session.declare_subscriber(self.keys[i].motor, zenoh.handlers.FifoChannel(1024))
                           for i in self._motor_bodies}
        self.queryables = [session.declare_queryable(k.params, zenoh.handlers.FifoChannel(64))
                           for k in self.keys]
        self.token = session.liveliness().declare_token(K.alive_key(self.scene, prefix=options.prefix))
        if live is not None:
            for k in self.keys:
                live.add_body(k)
        self.ros = None
        if options.ros_domain is not None:
            from .ros2 import Ros2Bridge

            tree = model.scene.tree or ()
            # the one-coordinate joints: hinges (rad) and sliders (m), as JointState's revolute and prismatic
            self._hinges = [b.name for b in tree if b.joint in ("hinge", "slider")]
            self._joint_coords = [("displacement", "velocity") if b.joint == "slider" else ("angle", "rate")
                                  for b in tree if b.joint in ("hinge", "slider")]
            self.ros = Ros2Bridge(session, options.ros_domain, self.scene, self.bodies, self._hinges,
                                  fixed=any(b.joint == "fixed" for b in tree), distro=options.ros_distro,
                                  torques=self._torque_bodies,
                                  motors={i: MOTOR_INPUTS[n][0] for i, n in self._motors.items()})

    # --------------------------------------------------------------------------------------------- inputs
    def body_inputs(self, body: int) -> dict[str, float]:
        """The inputs of one body by their short names (``tau_x``, ``motor_torque``)."""
        if self._input_names is None:
            return self.model.inputs(body)
        return {short: self.model.get(full) for short, full in self._input_names[body]}

    def _reject(self, key: str, reason: str, kind: str = "torque") -> None:
        setattr(self.stats, f"{kind}_rejected", getattr(self.stats, f"{kind}_rejected") + 1)
        self.stats.last_rejection = reason
        self._rejections_logged += 1
        n = getattr(self.stats, f"{kind}_rejected")
        if n <= 20 or n % 1000 == 0:
            log.warning("%s command on %s rejected (%d so far): %s", kind, key, n, reason)

    def _apply(self, kind: str, i: int, payload: bytes) -> None:
        """Validate one command of ``kind`` (torque, motor) for body ``i`` (its JSON payload: from the Zenoh key,
        or made from a ROS 2 message); set the inputs or reject it."""
        key = self.keys[i].key(kind)
        try:
            if kind == "torque":
                cmd = msg.parse_torque(payload, self.options.torque_limit)
                if i not in self._torque_bodies:
                    raise msg.TorqueRejected(f"body {self.bodies[i]!r} of scene {self.scene!r} has no "
                                             "torque input (scene: torque_input = true)")
            else:
                motor = self._motors.get(i)
                if motor is None:
                    raise msg.MotorRejected(f"body {self.bodies[i]!r} of scene {self.scene!r} has no motor "
                                            "input (a hinge or slider with motor_input = true)")
                cmd = self._parse_motor(payload, i, motor)
            for name, value in cmd.as_inputs().items():
                self.model.set(name, value, body=i)
        except msg.TorqueRejected as e:  # MotorRejected too
            self._reject(key, e.reason, kind)
            return
        except ConfigError as e:  # the model refused it
            self._reject(key, str(e), kind)
            return
        setattr(self.stats, f"{kind}_accepted", getattr(self.stats, f"{kind}_accepted") + 1)
        if self._file is not None:
            self._file.overridden(i, cmd.as_inputs(), self.model.time)
        if self.recorder is not None:
            encoding = (msg.TORQUE_ENCODING if kind == "torque" else msg.MOTOR_FORCE_ENCODING
                        if isinstance(cmd, msg.MotorForce) else msg.MOTOR_ENCODING)
            self.recorder.write_sample(key, encoding, payload, publish_time_ns=msg.seconds_to_ns(self.model.time))
        if kind == "torque":
            log.info("torque on %s: %s N*m", self.bodies[i], (cmd.x, cmd.y, cmd.z))
        elif isinstance(cmd, msg.MotorForce):
            log.info("motor force on %s: %s N", self.bodies[i], cmd.force)
        else:
            log.info("motor torque on %s: %s N*m", self.bodies[i], cmd.torque)

    def _parse_motor(self, payload, i: int, motor: str):
        """Body ``i``'s joint motor command (``motor``: its input, motor_torque or motor_force); the other joint's
        command sent to it is refused by name."""
        parsers = {"motor_torque": lambda limit: msg.parse_motor(payload, limit),
                   "motor_force": lambda limit: msg.parse_motor_force(payload, limit)}
        limits = {"motor_torque": self.options.torque_limit, "motor_force": self.options.force_limit}
        try:
            return parsers[motor](limits[motor])
        except msg.TorqueRejected as first:
            other = next(n for n in MOTOR_INPUTS if n != motor)
            try:
                parsers[other](math.inf)
            except msg.TorqueRejected:
                raise first from None  # not the other joint's command either: the first reason
            member, unit, joint = MOTOR_INPUTS[motor]
            raise msg.MotorRejected(f"body {self.bodies[i]!r} of scene {self.scene!r} is on a {joint}: its motor "
                                    f"command is {{\"{member}\": x}} in {unit}, not "
                                    f"{{\"{MOTOR_INPUTS[other][0]}\"}}") from None

    def commands_text(self) -> str:
        """The command keys subscribed and what each takes, e.g. ``.../cart/motor {"force"} N``, or ``none``."""
        parts = [f"{self.keys[i].torque} {{\"x\", \"y\", \"z\"}} N*m" for i in self._torque_bodies]
        for i, motor in self._motors.items():
            member, unit, _ = MOTOR_INPUTS[motor]
            parts.append(f"{self.keys[i].motor} {{\"{member}\"}} {unit}")
        return ", ".join(parts) or "none (no body has a torque or motor input)"

    def apply_file_inputs(self) -> None:
        """Set the input file's values at the model's current time (those a Zenoh command overrides kept)."""
        if self._file is not None:
            self._file.apply(self.model.time)

    def poll_inputs(self) -> None:
        """Apply queued torque and motor commands and answer queued params queries (stepping thread only)."""
        for kind, subs in (("torque", self.torque_subs), ("motor", self.motor_subs)):
            for i, sub in subs.items():
                while (sample := sub.try_recv()) is not None:
                    self._apply(kind, i, sample.payload.to_bytes())
        if self.ros is not None:  # commands from ROS 2 topics: the same checks
            while self.ros.commands:
                kind, i, payload, force = self.ros.commands.popleft()
                if force is not None and any(f != 0.0 for f in force):
                    self._reject(self.keys[i].key(kind), f"a Wrench with force {force} N: only its torque is an "
                                 "input of a body (send force = 0)", kind)
                    continue
                self._apply(kind, i, payload)
        for i, q in enumerate(self.queryables):
            while (query := q.try_recv()) is not None:
                self.stats.queries += 1
                try:
                    query.reply(self.keys[i].params, msg.encode_params(self.params_info(i)),
                                encoding=msg.PARAMS_ENCODING)
                except Exception as e:  # a query that went away must not stop the service
                    log.warning("params reply on %s failed: %s", self.keys[i].params, e)
                finally:
                    query.drop()

    def body_parameters(self, body: int) -> dict:
        """The parameters of one body by their short names; a tree body's also the scene-wide ones (``g``,
        ``integrator``, ``max_step``, scene parameters such as ``L1``), which have no body prefix."""
        if self._input_names is None:
            return self.model.parameters(body)
        every = self.model.parameters()
        split = {n: self.model.scene.split_name(n) for n in every}
        out = {n: v for n, v in every.items() if split[n][0] is None}
        out.update({split[n][1]: v for n, v in every.items() if split[n][0] == body})
        return out

    def params_info(self, body: int) -> dict:
        """What a ``.../params`` query answers for one body."""
        m = self.model
        info = {
            "scene": self.scene, "body": self.bodies[body], "time": m.time,
            "parameters": self.body_parameters(body), "inputs": self.body_inputs(body),
            "service": {"rate": self.options.rate, "realtime_factor": self.options.realtime_factor,
                        "torque_limit": self.options.torque_limit, "prefix": self.options.prefix,
                        "stats": asdict(self.stats)},
        }
        if self.tree is not None:
            f = self.tree.bodies[body]
            info.update(parent=f.parent, joint=f.joint)
        return info

    # ------------------------------------------------------------------------------------------- stepping
    def publish(self) -> None:
        """Publish (and record) every body's state, tf and imu at the model's current time, one way for every
        scene: each body's frame from its parent's (:meth:`_frames`), then the same messages for each."""
        m = self.model
        t = m.time
        t_ns = msg.seconds_to_ns(t)
        ros_frames = []
        accel = m.specific_force()   # what an accelerometer at each body's origin reads (body frames)
        for i, (body, parent, joint, f, state, contacts) in enumerate(self._frames(t)):
            wall = time.time_ns()
            acc = tuple(float(a) for a in accel[i])
            # the body's frame from its parent's, then its contact points' from the world
            transforms = [(body, parent, f.rotation, f.translation), *contacts]
            payloads = (("state", msg.STATE_ENCODING, msg.encode_state(state(wall))),
                        ("tf", msg.TF_ENCODING, msg.encode_tf_frames(t, transforms)),
                        ("imu", msg.IMU_ENCODING, msg.encode_imu(t, f.q_world, f.omega, frame_id=body,
                                                                 linear_acceleration=acc)))
            live_tf = None
            if self.live is not None:  # foxglove.FrameTransform: one message per transform
                live_tf = [msg.encode_frame_transform(t, q, child_frame_id=child, parent_frame_id=frame_id,
                                                      translation=tr) for child, frame_id, q, tr in transforms]
            self._emit(i, payloads, wall, t_ns, live_tf)
            if self.ros is not None:
                ros_frames.append(Frame(body, parent, f.rotation, f.translation, f.q_world, f.omega,
                                        joint == "fixed", acc, tuple(contacts)))
        if self.ros is not None:
            joints = None
            if self._hinges:
                out, name = m.outputs(), m.scene.var_name
                joints = ([out[name(h, c[0])] for h, c in zip(self._hinges, self._joint_coords)],
                          [out[name(h, c[1])] for h, c in zip(self._hinges, self._joint_coords)])
            self.stats.published += self.ros.publish(t, ros_frames, joints)

    def _frames(self, t: float):
        """``(body, parent frame, joint, FrameState, state(wall_ns) -> BodyState, contact transforms)`` for every
        body at time ``t``: a tree's from :class:`TreeFrames` (each body from its parent's frame; the contact points
        of its shapes as ``(frame, "world", rotation, point)``), a one-body scene's bodies from the world (their
        attitude, no translation; the state message with their ZYZ angles, momentum and energy; no contact)."""
        m = self.model
        if self.tree is not None:
            out = m.outputs()
            scene_out = {k: out[k] for k in SCENE_OUTPUTS if k in out}
            for i, (body, frame, f) in enumerate(zip(self.bodies, self.tree.bodies, self.tree.at(out))):
                mine = self._contacts[i]
                transforms = [(c.frame_id, msg.WORLD_FRAME, c.rotation, tuple(out[k] for k in c.point_keys))
                              for c in mine]
                values = [{"shape": c.shape, "plane": c.plane, "frame": c.frame_id,
                           **{q: out[k] for q, k in zip(CONTACT_STATE, c.value_keys)}} for c in mine]

                def state(wall, i=i, body=body, frame=frame, f=f, values=values):
                    return msg.BodyState.from_tree_outputs(
                        t, self._seq[i], q_world=f.q_world, omega=f.omega, parent=frame.parent,
                        joint_type=frame.joint, joint=f.joint, scene_outputs=scene_out, inputs=self.body_inputs(i),
                        scene=self.scene, body=body, wall_ns=wall, contacts=values)
                yield body, frame.parent, frame.joint, f, state, transforms
            return
        for i, body in enumerate(self.bodies):
            out = m.outputs(i)
            q = (out["q_w"], out["q_x"], out["q_y"], out["q_z"])
            omega = (out["omega_x"], out["omega_y"], out["omega_z"])

            def state(wall, i=i, body=body, out=out):
                return msg.BodyState.from_outputs(t, self._seq[i], out, m.inputs(i), scene=self.scene, body=body,
                                                  wall_ns=wall)
            yield body, msg.WORLD_FRAME, "free_rotation", FrameState((0.0, 0.0, 0.0), q, q, omega, {}), state, []

    def _emit(self, i: int, payloads, wall: int, t_ns: int, live_tf: list[bytes] | None) -> None:
        """Put one body's payloads ((kind, encoding, bytes) for state, tf, imu), record them, stream them live
        (``live_tf``: the tf's transforms as ``foxglove.FrameTransform`` JSON, one message each)."""
        pubs = self.publishers[i]
        for kind, encoding, data in payloads:
            pubs[kind].put(data)
            if self.recorder is not None:
                self.recorder.write_sample(self.keys[i].key(kind), encoding, data, log_time_ns=wall,
                                           publish_time_ns=t_ns, sequence=self._seq[i])
                self.stats.recorded += 1
        if self.live is not None:
            key = self.keys[i]
            self.live.log(key.state, payloads[0][2], wall)
            for data in live_tf:
                self.live.log(key.tf, data, wall)
            self.live.log(key.imu, payloads[2][2], wall)
        self.stats.published += len(payloads)
        self._seq[i] += 1

    def wait_for_subscribers(self, timeout: float, stop: threading.Event) -> bool:
        """Wait until every state publisher has a matching subscriber (or ``timeout`` s); True if all do."""
        deadline = time.monotonic() + timeout
        while not stop.is_set():
            if all(p["state"].matching_status.matching for p in self.publishers):
                return True
            if time.monotonic() >= deadline:
                return False
            self.poll_inputs()
            time.sleep(0.01)
        return False

    def _warm_up(self) -> None:
        """One step on a saved state, then restore it: warms caches (and the CDR encoders) before the clock runs."""
        m = self.model
        try:
            saved = m.get_state()
        except Exception:  # a model without state saving: no warm-up
            return
        try:
            m.step(self.h)
        except GyrosimError:
            pass
        finally:
            m.set_state(saved)
        msg.encode_tf(0.0, (1.0, 0.0, 0.0, 0.0), child_frame_id="warm-up")  # builds the CDR encoders once
        msg.encode_imu(0.0, (1.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), frame_id="warm-up")

    def run(self, stop: threading.Event) -> ServeStats:
        """Publish the initial state, then step and publish until ``duration`` or ``stop``."""
        o, m, st = self.options, self.model, self.stats
        self._warm_up()
        if o.wait_subscribers > 0:
            if self.wait_for_subscribers(o.wait_subscribers, stop):
                log.info("subscribers present on every state key")
            else:
                log.warning("no subscriber on some state key after %.1f s; starting anyway",
                            o.wait_subscribers)
        t0 = m.time
        n_steps = None if o.duration is None else int(round(o.duration * o.rate))
        self.poll_inputs()
        self.apply_file_inputs()
        self.publish()
        wall0 = time.monotonic()
        log.info("stepping: h = %g s, %s", self.h,
                 f"{o.duration:g} s simulated" if o.duration is not None else "until stopped")
        n = 0
        last_flush_poll = wall0
        wall_end = None if o.wall_duration is None else wall0 + o.wall_duration
        while not stop.is_set() and (n_steps is None or n < n_steps):
            if wall_end is not None and time.monotonic() >= wall_end:
                st.stopped_by = st.stopped_by or "wall duration"
                break
            if o.realtime_factor > 0:
                target = wall0 + (n + 1) * self.h / o.realtime_factor
                if wall_end is not None:
                    target = min(target, wall_end)
                while True:
                    now = time.monotonic()
                    remaining = target - now
                    if remaining <= 0 or stop.is_set():
                        break
                    time.sleep(min(remaining, 0.02))
                    if remaining > 0.02:
                        self.poll_inputs()
                st.max_lag = max(st.max_lag, -remaining)
                if stop.is_set():
                    break
            self.poll_inputs()
            self.apply_file_inputs()
            try:
                m.step(self.h)
            except (IntegrationError, StepError) as e:
                st.stopped_by = f"model error: {e}"
                log.error("model step at t = %.6g s failed: %s", m.time, e)
                raise
            n += 1
            st.steps = n
            st.sim_time = m.time - t0
            self.publish()
            if self.recorder is not None and time.monotonic() - last_flush_poll > 0.1:
                self.recorder.maybe_flush()
                last_flush_poll = time.monotonic()
        st.wall_time = time.monotonic() - wall0
        if not st.stopped_by:
            st.stopped_by = "duration" if n_steps is not None and n >= n_steps else "stop request"
        return st

    def close(self) -> None:
        """Undeclare everything (publishers first, then the token)."""
        for pubs in self.publishers:
            for p in pubs.values():
                p.undeclare()
        for s in (*self.torque_subs.values(), *self.motor_subs.values()):
            s.undeclare()
        for q in self.queryables:
            q.undeclare()
        if self.ros is not None:
            self.ros.close()
        self.token.undeclare()


def main(conf, scene=None, *, options: ServeOptions = ServeOptions(), parameters: dict | None = None,
         model=None, stop: threading.Event | None = None, ready: Callable[[Service], None] | None = None
         ) -> ServeStats:
    """Serve a scene on Zenoh until ``options.duration`` simulated seconds or SIGINT/SIGTERM.

    Parameters
    ----------
    conf : zenoh.Config
        Session configuration (see :mod:`gyrosim.service.config`).
    scene : str, Scene or None
        Embedded scene name, TOML path, Scene, or None for the full model.
    options : ServeOptions
        Rate, pacing, duration, recording, limits.
    parameters : dict, optional
        Parameter values set on the model (``--set NAME=VALUE``, ``--integrator``).
    model : Model, optional
        A model to serve instead of building one from ``scene`` and ``parameters``.
    stop : threading.Event, optional
        Set it to stop; by default SIGINT and SIGTERM set it (in the main thread).
    ready : callable, optional
        Called with the :class:`Service` once everything is declared.

    Returns
    -------
    ServeStats

    Raises
    ------
    ConfigError, RecordingError, IntegrationError
        Bad scene or parameters, unwritable recording, model failure.
    """
    import zenoh

    from ..telemetry.recorder import Recorder, metadata_record

    if model is None:
        model = build_model(scene, parameters)
    inputs = None
    if options.input_file is not None:  # read and checked against the scene before anything starts
        from ..inputs import read_input_file

        inputs = read_input_file(options.input_file)
        inputs.check_against(model)
        log.info("inputs from %s: %s (%d rows, t = %g .. %g s)", options.input_file, ", ".join(inputs.names),
                 len(inputs.time), inputs.time[0], inputs.time[-1])
    stop = stop if stop is not None else threading.Event()
    recorder = None
    record_metadata = None
    if options.record:
        Recorder.check_writable(options.record)  # created once the session is up: a failed start keeps a file
        frames = None
        if model.scene.kernel == "tree":  # one system: its parameters by full name, and its frames
            params = model.parameters()
            first = params
            frames = [{"body": b.name, "parent": model.body_names[b.parent] if b.parent >= 0 else msg.WORLD_FRAME,
                       "joint": b.joint} for b in model.scene.tree]
        else:
            params = {b: model.parameters(i) for i, b in enumerate(model.body_names)}
            first = model.parameters(0) if model.body_names else {}
        record_metadata = metadata_record(
            scene=model.scene.name, parameters=params, integrator=first.get("integrator"),
            rate=options.rate, realtime_factor=options.realtime_factor, prefix=options.prefix,
            bodies=list(model.body_names), frames=frames, source="gyrosim serve", input_file=options.input_file)
    service = None
    stats = ServeStats()
    live = None
    restore = install_stop_signals(stop, stats)
    try:
        if options.foxglove is not None:
            from .live import LiveView

            live = LiveView(*options.foxglove, name=f"gyrosim serve {model.scene.name}",
                            bodies=[K.BodyKeys(model.scene.name, b, options.prefix) for b in model.body_names])
        if options.ros_domain is not None:  # /tf_static's advanced publisher stamps its samples (as rmw_zenoh)
            conf.insert_json5("timestamping/enabled", "true")
        with open_session(conf, log=log) as session:
            if options.record:  # beside the target until the first message: a run that publishes nothing keeps it
                recorder = Recorder(options.record, metadata=record_metadata, keep_until_message=True)
            service = Service(session, model, options, recorder, live, inputs)
            service.stats = stats
            log.info("serving scene %r (bodies: %s) on %s/%s/... at %g Hz, realtime factor %g",
                     service.scene, ", ".join(service.bodies), options.prefix, service.scene, options.rate,
                     options.realtime_factor)
            log.info("commands taken: %s", service.commands_text())
            if ready is not None:
                ready(service)
            try:
                service.run(stop)
            finally:
                if options.linger > 0:
                    time.sleep(options.linger)
                service.close()
    except zenoh.ZError as e:
        raise zenoh_error(e, conf) from None
    finally:
        restore()
        if live is not None:
            live.close()
        if recorder is not None:
            summary = recorder.close()
            if summary.messages:
                log.info("recording: %s", summary.format().splitlines()[0])
    if recorder is not None and not summary.messages:
        stats.record_empty = True
        peers = describe_endpoints(conf)
        log.warning("--record: nothing published on %r%s: %s", f"{options.prefix}/{model.scene.name}/**",
                    f" ({peers})" if peers else "", f"{recorder.path!r} not written (an existing file of that name "
                    "is as it was)" if summary.discarded else f"{recorder.path!r} holds no message")
    return stats
