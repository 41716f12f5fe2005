"""The step-based model: Scene -> Model(parameters, inputs) -> step(h) -> outputs, with exact state save/restore.

One class for every scene. ``gyrosim simulate``, the Zenoh service, the sweeps, the analyses and the study drive
it; it maps the scene's variable table onto the C engine, which does every step. The engine's kernel is picked
when the scene is set up (:attr:`gyrosim.scene.Scene.kernel`, docs/trees.md): the model's operations that depend
on it (how variables map onto the engine's rows, the engine calls, the advice of a blow-up) are that kernel's
(:class:`gyrosim.kernel_body.BodyKernel`, :class:`gyrosim.kernel_tree.TreeKernel`); everything else (the clock,
stepping, state save and restore, the analyses) is here, once. The FMUs compile the same engine, so a run here and
a run of an FMU give the same bits.
"""

from __future__ import annotations

import copy
import math
import pickle
from dataclasses import dataclass

import numpy as np

from .core import _engine
from .errors import ConfigError, StepError
from .kernel_body import OUTPUT_NAMES, BodyKernel, variables_for
from .kernel_tree import TreeKernel
from .scene import INTEGRATORS, TREE_INTEGRATORS, did_you_mean, load_scene
from .variables import Variable

__all__ = ["Model", "Variable", "ModelState", "variables_for", "OUTPUT_NAMES"]


def _positive_step(h, what: str) -> float:
    """``h`` as a finite float > 0 (s), or a StepError naming ``what`` and the value."""
    try:
        x = float(h)
    except (TypeError, ValueError):
        x = math.nan
    if not (math.isfinite(x) and x > 0.0):
        raise StepError(f"{what} = {h!r} is not allowed: a finite number > 0 in s")
    return x


@dataclass
class ModelState:
    """An exact snapshot of a :class:`Model` (arrays copied; picklable)."""

    data: dict


class Model:
    """Step-based model of any scene: independent bodies or a tree of bodies joined by joints.

    Parameters
    ----------
    scene : str, Path, Scene or None
        Embedded scene name (``free_body``, ``heavy_top``, ``gyroscope``), a TOML path, a :class:`Scene`, or
        ``None`` for the full model with every variable.
    parameters : dict, optional
        Initial values by variable name (applied to every body), e.g. ``{"I1": 2.0, "integrator": "rk4"}``.
    start_time : float
        s.
    stop_time : float, optional
        s; a step that would end beyond it raises :class:`StepError` (round-off of 1e-9 relative allowed).
    tolerance : float, optional
        Relative and absolute tolerance of ``adaptive`` (the FMI tolerance); default the scene's.

    Examples
    --------
    >>> m = Model("free_body")
    >>> m.step(0.01)
    >>> round(m.time, 12)
    0.01
    >>> sorted(k for k in m.variables if k.startswith("tau"))   # a free body has no torque inputs
    []
    >>> Model("gimbal_gyroscope").get("rotor.rate") > 0   # a tree: <body>.<name>
    True
    """

    #: the kernels' operations by Scene.kernel
    _KERNELS = {"body": BodyKernel, "tree": TreeKernel}

    def __init__(self, scene=None, *, parameters: dict | None = None, start_time: float = 0.0,
                 stop_time: float | None = None, tolerance: float | None = None):
        self.scene = load_scene(scene)
        self._k = self._KERNELS[self.scene.kernel]
        self._k.setup(self)
        self._start(start_time, stop_time, tolerance, parameters)

    # ----------------------------------------------------------------------------------------------- the kernel's
    def set(self, name: str, value, body=None) -> None:
        """Set a parameter, input or start state by variable name: for one body (``body``: a name or index;
        ``<body>.<name>``) or every body; in a tree scene with copies (sweeps), for every copy.

        Raises
        ------
        ConfigError
            Unknown name, a derived output, or a value that is not allowed (named with the rule).
        """
        return self._k.set(self, name, value, body)

    def set_values(self, values: dict) -> None:
        """Set several parameters, inputs and start states by name (as :meth:`set`; an array of one value per system
        as :meth:`set_many`), then check the values that must hold together (a joint's stops in order, an
        impact-stopped joint within them) once: the order of the names does not matter. A refused value leaves the
        model as it was.

        Raises
        ------
        ConfigError
            As :meth:`set`; or the values together are not allowed (the scene file's message).
        """
        def set_all():
            for k, v in values.items():
                if isinstance(v, np.ndarray) and v.ndim == 1:
                    self.set_many(k, v)
                else:
                    self.set(k, v)

        together = getattr(self._k, "_together", None)   # a tree's: its stops (one body has none)
        state, integrator = self.get_state(), self.integrator
        self._defer_together = True
        try:
            set_all()
            if together is not None:
                together(self)
        except BaseException:
            self.set_state(state)
            self.integrator = integrator
            raise
        finally:
            self._defer_together = False

    def _set_integrator(self, value) -> None:
        """The integrator by name, one that the scene's system takes (``Scene.integrators``); a new one starts
        without the old one's history (the kernel's ``_forget``)."""
        allowed = self.scene.integrators
        if value in ("midpoint", "energy_momentum") and value not in allowed and self.scene.tree is not None:
            from .scene_tree import implicit_refusal

            raise ConfigError("integrator", value, implicit_refusal(self.scene.tree, self.scene.orbit,
                                                                    bool(self.scene.shapes)))
        if value in ("splitting", "splitting4") and value not in allowed and self.scene.tree is not None:
            from .scene_tree import split_refusal

            raise ConfigError("integrator", value, split_refusal())
        if value not in allowed:
            why = (f"{value!r} solves one body; a tree of bodies takes one of " if value in INTEGRATORS
                   else f"{value!r} integrates a tree of bodies (a scene with a `joint`); one body takes one of "
                   if value in TREE_INTEGRATORS else "one of ")
            raise ConfigError("integrator", value, why + ", ".join(allowed) + did_you_mean(value, allowed))
        if value != self.integrator:
            self._k._forget(self)
        self.integrator = value

    def set_many(self, name: str, values) -> None:
        """One value per system (``(n_systems,)``: the bodies of a one-body scene, the copies of a tree), names,
        rules and messages as :meth:`set` (sweeps). ``integrator``, ``max_step`` and ``max_drift`` hold for the
        whole model: set them with :meth:`set`.

        Raises
        ------
        ConfigError
            Unknown name, a model-wide or derived variable, a shape other than (n_systems,), or a value that is
            not allowed.
        """
        v = self._k._var(self, name)
        if v.type == "String" or name in ("max_step", "max_drift"):
            raise ConfigError(name, "an array", f"one value for every {self._k.SYSTEM}: use Model.set")
        try:
            x = np.asarray(values, dtype=float)
        except (TypeError, ValueError):
            raise ConfigError(name, values, f"an array of real numbers in {v.unit or '1'}") from None
        n = self.n_systems
        if x.shape != (n,):
            raise ConfigError(name, f"an array of shape {x.shape}", f"an array of shape ({n},)")
        self._k._assign_many(self, name, v, x)

    def get(self, name: str, *args, **kwargs):
        """Value of a variable by name (float, or str for ``integrator``): ``<body>.<name>``, or the name with
        ``body=``; of copy ``system=`` in a tree scene with copies."""
        return self._k.get(self, name, *args, **kwargs)

    def outputs(self, *args, **kwargs) -> dict[str, float]:
        """Every output by name (of one body with ``body=``)."""
        return self._k.outputs(self, *args, **kwargs)

    def outputs_array(self) -> np.ndarray:
        """(n_systems, n_outputs) outputs in the order of ``scene.output_names()`` per system (a copy)."""
        return self._k.outputs_array(self)

    def parameters(self, *args, **kwargs) -> dict:
        """Current parameters by name."""
        return self._k.parameters(self, *args, **kwargs)

    def inputs(self, *args, **kwargs) -> dict[str, float]:
        """Current inputs by name (empty when the scene has none)."""
        return self._k.inputs(self, *args, **kwargs)

    def initialize(self) -> None:
        """Take the parameters and start the state (quaternions normalised, the health monitor started); done by
        the first step (FMI: exit initialisation).

        Raises
        ------
        ConfigError
            Parameters or start values that are not allowed (moments breaking the triangle inequality, a
            non-unit quaternion, ...).
        """
        return self._k.initialize(self)

    def trajectory(self, dt: float, n: int, *, angles: bool = True, momentum: bool = True,
                   status: np.ndarray | None = None) -> np.ndarray:
        """Advance ``n`` output intervals of ``dt`` s in one engine call: ``(n + 1, n_systems, n_outputs)`` rows
        at ``time + k*dt``, ``k = 0..n``; the kernel's ``trajectory`` tells which integrators give the bits of a
        loop of :meth:`step`. ``status``: an (n_systems,) int32 array to keep going when systems blow up (sweeps).

        Raises
        ------
        StepError
            ``dt`` not finite or <= 0, ``n`` < 0, or the run would end after the stop time.
        IntegrationError
            A system blew up (without ``status``); the model keeps its state from before the call, and the error
            carries the rows computed before the failing interval (``error.rows``).
        """
        return self._k.trajectory(self, dt, n, angles=angles, momentum=momentum, status=status)

    def dynamics_kernel(self, system: int = 0) -> str:
        """The right-hand side the engine runs for system ``system`` with its parameters now: ``"rigid_body"`` (a
        one-body scene's engine), or for a tree ``"articulated_body"`` (Featherstone's algorithm, any tree),
        ``"gyrostat"`` (a hub on a ball joint carrying rotors) or ``"gimbal"`` (a rotor in two gimbals), the closed
        forms the engine picks at set-up where a tree has their shape (docs/engine.md)."""
        return self._k.dynamics_kernel(self, system)

    def specific_force(self, body=None, system: int = 0) -> np.ndarray:
        """What an accelerometer at a body's frame origin reads: the specific force a - g (m/s^2, the origin's
        acceleration in the world minus gravity), in the body's frame; a body at rest on a support reads +g along
        the world's up. ``body``: a name or index (``None``: every body, ``(n_bodies, 3)``); of copy ``system``.

        The acceleration is the time derivative of the origin's world velocity (``<body>.v_world_*``) along the
        state's derivative, by the engine's complex step (exact to round-off, no difference quotient).
        """
        f = self._k.specific_force(self, system)
        if body is None:
            return f
        if isinstance(body, str):
            if body not in self.body_names:
                raise ConfigError("body", body, f"one of {', '.join(self.body_names)}")
            body = self.body_names.index(body)
        return f[int(body)]

    def on_face(self, system: int = 0) -> list[str]:
        """The rigid contacts of copy ``system`` lying flat on a face: a disk or cylinder that has landed on it
        (Euler's disk's finite-time end: docs/engine.md) or started on it. Their outputs' stems (``rim``,
        ``disk.rim.floor``): ``<stem>.mode`` reads 3 once the face rests."""
        return self._k.on_face(self, system)

    def fastest_rate(self, system: int = 0) -> float:
        """The fastest rate (rad/s) in system ``system``'s state: the step-size scale of its dynamics."""
        return self._k.fastest_rate(self, system)

    # What the analyses, the sweeps, the service and gyrosim.simulate ask of any model, answered by its kernel:
    # how many independent systems it steps (rows of its state), where each one's coordinates are in a state row,
    # how to restart rows from new coordinates, what its health monitor measures.
    @property
    def n_systems(self) -> int:
        """Independent systems the model steps, one state row each: the bodies of a one-body scene, the copies of
        a tree (the sweeps' replicas)."""
        return self._k.n_systems(self)

    @property
    def coordinates(self) -> list[tuple[str, str, int]]:
        """A system's continuous coordinates: (variable name, coordinate, slot in its state row), in slot order."""
        return self._k.coordinates(self)

    @property
    def n_coords(self) -> int:
        """The state row's continuous coordinates (the slots after them are the health monitor's)."""
        return self._k.n_coords(self)

    @property
    def input_names(self) -> list[str]:
        """The inputs by full name (``tau_x``; ``<body>.tau_x``, ``<body>.motor_torque`` with several bodies)."""
        return self._k.input_names(self)

    @property
    def trajectory_is_steps(self) -> bool:
        """Whether :meth:`trajectory` over several output intervals gives the bits of a loop of :meth:`step` with
        the integrator set (inputs held over intervals may then be applied a block of intervals at a time)."""
        return self._k.trajectory_is_steps(self)

    def trajectory_is_steps_for(self, dt: float) -> bool:
        """:attr:`trajectory_is_steps` for output intervals of ``dt`` s: a tree's euler and rk4 take steps longer
        than the interval where max_step is (their outputs then come from the continuous extension)."""
        return self._k.trajectory_is_steps(self, dt)

    @property
    def ROWS_DIRECT(self) -> bool:  # noqa: N802 - the kernel's constant
        """Whether the engine writes a lone system's result rows itself (gyrosim.simulate's fast path)."""
        return self._k.ROWS_DIRECT

    @property
    def _STATE_FIELDS(self) -> tuple:  # noqa: N802 - the kernel's constant
        return self._k._STATE_FIELDS

    def inert_bodies(self, system: int = 0) -> list:
        """The bodies that carry no inertia at their joint (the kernel's rule; none on the one-body kernel)."""
        return self._k.inert_bodies(self, system)

    def gimbal_lock(self, y=None, system: int = 0) -> str | None:
        """A message naming gimbal lock where two hinge axes of a chain line up, else None (trees)."""
        return self._k.gimbal_lock(self, y, system)

    def drift_measure(self, out0: np.ndarray) -> tuple:
        """What the sweeps measure of each system's drift from its outputs at the start ``out0``: (energy
        scales, momentum scales, ``drifts(traj)``, the trajectory's options)."""
        return self._k.drift_measure(self, out0)

    def _check_call(self, h: float, what: str) -> None:
        self._k._check_call(self, h, what)

    def _outputs_array(self) -> np.ndarray:
        return self._k._outputs_array(self)

    def _columns(self, name: str) -> list:
        return self._k._columns(self, name)

    def _trajectory(self, dt, n, angles: bool, momentum: bool, status, restore: bool) -> np.ndarray:
        return self._k._trajectory(self, dt, n, angles, momentum, status, restore)

    def _trajectory_select(self, *args, **kwargs):
        return self._k._trajectory_select(self, *args, **kwargs)

    def _replica(self) -> Model:
        return self._k._replica(self)

    def _replicable(self) -> bool:
        return self._k._replicable(self)

    def _restart_rows(self, rows: np.ndarray, coords: np.ndarray) -> int:
        return self._k._restart_rows(self, rows, coords)

    def _restored(self) -> None:
        self._k._restored(self)

    # ----------------------------------------------------------------------------------------------- common
    def _start(self, start_time, stop_time, tolerance, parameters) -> None:
        """The scene's integrator settings, the clock at ``start_time``, nothing initialised yet; then
        ``parameters`` set by name."""
        self.integrator = self.scene.integrator
        self.max_step = float(self.scene.max_step)
        self.max_drift = float(self.scene.max_drift)
        self.tolerance = float(self.scene.tolerance if tolerance is None else tolerance)
        if tolerance is not None:
            self._check_positive("tolerance", self.tolerance)
        self.start_time = float(start_time)
        self.stop_time = None if stop_time is None else float(stop_time)
        self._t_base = self.start_time
        self._n = 0
        self._h = 0.0
        self._initialized = False
        self._state_dirty = True
        self._out = None
        if parameters or getattr(self.scene, "shapes", ()) or getattr(self.scene, "loops", ()):
            # the values that hold together checked once (a rigid contact's start on its plane, a loop that closes:
            # the scene file's own start too, which no set call checks)
            self.set_values(dict(parameters or {}))

    # ----------------------------------------------------------------------------------------------- variables
    @property
    def time(self) -> float:
        """Current time in s: ``t_base + n*h`` over each run of equal steps (no accumulated round-off)."""
        return self._t_base + self._n * self._h

    @staticmethod
    def _check_positive(name, value):
        if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value > 0):
            raise ConfigError(name, value, "a finite number > 0")

    def set_tolerance(self, tolerance: float) -> None:
        """Relative and absolute tolerance of ``adaptive`` (the FMI tolerance)."""
        self._check_positive("tolerance", tolerance)
        self.tolerance = float(tolerance)

    def _refuse_work(self, h: float, what: str) -> None:
        """The StepError of a call that needs more internal steps than one call may take."""
        article = "an" if what[:1] in "aeiou" else "a"
        raise StepError(f"{article} {what} of {h!r} s with max_step = {self.max_step!r} s needs "
                        f"{h / self.max_step:.3g} "
                        f"internal steps, more than the {_engine.MAX_WORK:,} one call may take; raise max_step "
                        "or take shorter steps")

    def _tick(self, t: float, h: float, k: int) -> None:
        """The clock after ``k`` steps of ``h`` s from ``t``: a run of equal steps stays ``t_base + n*h``."""
        if k:
            if h == self._h:
                self._n += k
            else:
                self._t_base = t
                self._n = k
                self._h = h
        self._out = None

    def _start_run(self, dt, n, status, copies: int) -> tuple[float, int, float]:
        """A trajectory's checks (status array, dt, n, the stop time) and the model initialised: (dt, n, t)."""
        if status is not None and not (isinstance(status, np.ndarray) and status.dtype == np.int32
                                       and status.shape == (copies,)):
            raise ConfigError("status", type(status).__name__, f"an int32 array of shape ({copies},)")
        if not (type(dt) is float and 0.0 < dt < math.inf):  # a plain float > 0 passes as it is
            dt = _positive_step(dt, "output interval dt")
        if type(n) is not int:
            if not (isinstance(n, (int, np.integer)) and n >= 0):
                raise StepError(f"n = {n!r} is not allowed: a number of output intervals >= 0")
            n = int(n)
        elif n < 0:
            raise StepError(f"n = {n!r} is not allowed: a number of output intervals >= 0")
        t = self._t_base + self._n * self._h  # self.time
        t_end = t + n * dt
        if self.stop_time is not None and t_end > self.stop_time + 1e-9 * max(1.0, abs(self.stop_time)):
            raise StepError(f"a run of {n} intervals of {dt!r} s from t = {t!r} s ends at {t_end!r} s, after the "
                            f"stop time {self.stop_time!r} s")
        if not self._initialized or self._state_dirty:
            self.initialize()
        self._check_call(dt, "output interval dt")
        return dt, n, t

    def step(self, h: float) -> None:
        """Advance one communication step of ``h`` s, holding the inputs.

        Raises
        ------
        StepError
            ``h`` not finite or <= 0, or the step would end after the stop time.
        IntegrationError
            The integrator produced a non-finite or exploding state; the model keeps its state from before the
            step, so a smaller ``max_step`` or another integrator can retry it.
        """
        h = _positive_step(h, "communication step h")
        t = self.time
        if self.stop_time is not None and t + h > self.stop_time + 1e-9 * max(1.0, abs(self.stop_time)):
            raise StepError(f"a step of h = {h!r} s from t = {t!r} s ends at {t + h!r} s, after the stop time "
                            f"{self.stop_time!r} s")
        if not self._initialized or self._state_dirty:
            self._k.initialize(self)
        if self.integrator == "exact" or h > self.max_step * 1e6:
            self._check_call(h, "communication step h")
        self._k._step_engine(self, h, t)
        self._tick(t, h, 1)

    @property
    def stats(self) -> dict[str, int]:
        """Accumulated internal steps, rejected steps and right-hand-side evaluations (all bodies)."""
        s = self._stats.sum(axis=0)
        return {"steps": int(s[0]), "rejected": int(s[1]), "rhs_evaluations": int(s[2])}

    # ----------------------------------------------------------------------------------------------- analyses
    def jacobian(self, *, system: int = 0):
        """The engine's derivatives at the present state (A, B, C, D and names; quaternions as four numbers), by
        the complex step: :func:`gyrosim.analysis.linear.jacobian`."""
        from .analysis.linear import jacobian

        return jacobian(self, system=system)

    @property
    def closed(self) -> bool:
        """True for a scene with closed loops or gears: its state lives on their manifold, onto which the engine
        projects every start and step."""
        return bool(getattr(self.scene, "loops", ()) or getattr(self.scene, "gears", ()))

    def mobility(self, system: int = 0) -> dict | None:
        """A mechanism's degrees of freedom at its assembled start (a scene with closed loops or gears; None
        without): ``{"mobility": m, "joint_dof": n, "rows": r, "rank": k}`` with m = n - k, k the rank of the loops'
        and gears' rows as the constraint solve finds it (redundant rows do not count: the Bricard mechanism has
        mobility 1 where Gruebler's count gives 0). m = 0: the mechanism is locked."""
        if not self.closed:
            return None
        from .core import _engine

        m, k, r = _engine.tree_mobility(self.layout.desc, self._y[system:system + 1], self._pp[system:system + 1])
        return {"mobility": m, "joint_dof": m + k, "rows": r, "rank": k}

    def locked_text(self) -> str | None:
        """One line where the mechanism is locked (mobility 0), else None."""
        mob = self.mobility()
        if mob is None or mob["mobility"] > 0:
            return None
        return (f"the mechanism is locked: its loops and gears ({mob['rows']} rows of rank {mob['rank']}) take all "
                f"{mob['joint_dof']} of its joints' degrees of freedom, so nothing moves but what the constraint "
                "forces hold")

    def linearize(self, *, about=None, system: int = 0):
        """State-space matrices and normal modes about the present state, an equilibrium or a steady motion:
        ``A, B, C, D, names = model.linearize()``; the result also has ``.modes``, ``.stability`` and ``.table()``
        (:func:`gyrosim.analysis.linear.linearize`, which lists the values of ``about``)."""
        from .analysis.linear import linearize

        return linearize(self, about=about, system=system)

    def lyapunov(self, *args, **kwargs):
        """The largest Lyapunov exponent of a run from the present state (:func:`gyrosim.analysis.chaos.lyapunov`,
        which lists the arguments)."""
        from .analysis.chaos import lyapunov

        return lyapunov(self, *args, **kwargs)

    def get_state(self) -> ModelState:
        """Snapshot of the whole state, integrator history included, exact to the bit."""
        return ModelState({k: copy.deepcopy(getattr(self, k)) for k in self._STATE_FIELDS})

    def set_state(self, state: ModelState) -> None:
        """Restore a snapshot taken with :meth:`get_state` (of a model of the same scene)."""
        if not isinstance(state, ModelState) or set(state.data) != set(self._STATE_FIELDS):
            raise ConfigError("state", type(state).__name__, f"a ModelState from {type(self).__name__}.get_state()")
        if state.data["_y"].shape != self._y.shape:
            raise ConfigError("state", f"a state of shape {state.data['_y'].shape}",
                              f"a state of this scene (shape {self._y.shape}: {self.n_bodies} bodies)")
        for k, v in state.data.items():
            setattr(self, k, copy.deepcopy(v))
        self._out = None
        self._restored()

    def state_bytes(self) -> bytes:
        """The state serialised (FMI serialized FMU state)."""
        return pickle.dumps(self.get_state().data, protocol=pickle.HIGHEST_PROTOCOL)

    def set_state_bytes(self, data: bytes) -> None:
        """Restore a state from :meth:`state_bytes`."""
        try:
            d = pickle.loads(bytes(data))
        except Exception as e:  # noqa: BLE001 - any corrupt blob is a ConfigError
            raise ConfigError("state", f"{len(data)} bytes", f"a state serialised by Model.state_bytes ({e})")\
                from None
        self.set_state(ModelState(d))

