"""The Python side of the gyrosim FMUs: a thin FMI facade around :class:`gyrosim.model.Model`.

This module is copied into every FMU (under the FMU's unique package name) and driven by the FMU's C bridge
(:mod:`gyrosim.fmu.bridge`), which calls the methods below by name. It keeps no physics: every value goes to or
comes from the :class:`~gyrosim.model.Model`.

Rules the methods follow:

* No exception leaves a method: errors are logged with status Error (category ``logStatusError``) in
  ``log_queue``, as ``(status, category, message)`` tuples; the bridge passes the queue to the host's logger
  after every call and returns ``Error`` for a call that logged an error. Getters then return NaN (or ``""``)
  of the right length. (An exception that escapes anyway is logged by the bridge as an Error too.)
* A call in the wrong state, a bad value or a refused step leaves the instance as it was (usable); the
  state masks follow the Modelica Reference FMUs.
* The FMU state is the whole :class:`Model` state (``Model.state_bytes``), bit for bit.
* Fast path: :meth:`_Core._fast_info` tells the bridge when a plain doStep may run in C (a numba cfunc on the
  model's own arrays, :mod:`gyrosim.fmu.fast`), and :meth:`_Core._sync_clock` gives the model back the clock
  the bridge kept meanwhile.

Value references: ``1 + i`` for the ``i``-th variable of ``Model.variables`` (in order); FMI 3.0 also has
``time`` (independent) at 0. :func:`fmu_variables` is the single source of that numbering for the
modelDescription writer and for this runtime.
"""

from __future__ import annotations

import math
import os
import pickle

from ..core import kernels
from ..errors import GyrosimError
from ..model import OUTPUT_NAMES, Model

__all__ = ["Fmi2Slave", "Fmi3Slave", "fmu_variables", "LOG_CATEGORIES"]

LOG_CATEGORIES = {
    "logStatusWarning": "Log messages with status Warning.",
    "logStatusError": "Log messages with status Error: refused calls, invalid values, failed steps.",
    "logStatusFatal": "Log messages with status Fatal.",
    "logEvents": "Log the calls that change the FMU's state (initialization, termination, FMU state).",
}

# FMI states (bit masks, as in the Reference FMUs)
INSTANTIATED = 1
INITIALIZATION_MODE = 2
STEP_COMPLETE = 4  # FMI 3.0 step mode
TERMINATED = 8
_STATE_NAMES = {INSTANTIATED: "Instantiated", INITIALIZATION_MODE: "InitializationMode",
                STEP_COMPLETE: "StepComplete", TERMINATED: "Terminated"}

_OK, _WARNING, _DISCARD, _ERROR = 0, 1, 2, 3
_DERIVED = {"phi", "theta", "psi", "L_x", "L_y", "L_z", "energy"}
_TIME_TOL = 1e-9


def fmu_variables(model: Model) -> list[tuple[int, object]]:
    """``[(value_reference, Variable), ...]`` of the FMU of ``model``: ``1 + i`` in ``Model.variables`` order."""
    return [(i + 1, v) for i, v in enumerate(model.variables.values())]


class _Core:
    """State machine, variable access and FMU state shared by the FMI 2.0 and FMI 3.0 facades.

    Subclasses (generated per FMU) set ``SCENE`` to the scene TOML text, or ``None`` for the full model.
    """

    SCENE: str | None = None
    SCENE_SOURCE = "<fmu>"
    FMI = 2
    log_categories = LOG_CATEGORIES
    _scene_cache = None

    def __init__(self, **kwargs):
        self._kwargs = kwargs
        self.instance_name = kwargs.get("instance_name", "")
        self.resources = kwargs.get("resources")
        self.visible = kwargs.get("visible", False)
        self.log_queue = []
        self.vars = {}
        self._mode = INSTANTIATED
        self._experiment = (0.0, None, None)  # start time, stop time, tolerance
        self._pending = {}  # values set before initialization, replayed on the model of the experiment
        self.model = None
        try:
            self.model = self._new_model()
            self._by_vr = {vr: v for vr, v in fmu_variables(self.model)}
            self._out_index = {n: OUTPUT_NAMES.index(n) for n in OUTPUT_NAMES}
        except Exception as e:  # noqa: BLE001 - an exception would reach the bridge as an Error without context
            self._by_vr = {}
            self._error(f"cannot instantiate the model: {e}")

    # ------------------------------------------------------------------------------------------- helpers
    @classmethod
    def _scene(cls):
        if cls.SCENE is None:
            return None
        if cls._scene_cache is None:
            import tomllib

            from ..scene import scene_from_dict

            cls._scene_cache = scene_from_dict(tomllib.loads(cls.SCENE), cls.SCENE_SOURCE)
        return cls._scene_cache

    def _new_model(self, start_time=0.0, stop_time=None, tolerance=None) -> Model:
        return Model(self._scene(), start_time=start_time, stop_time=stop_time, tolerance=tolerance)

    def log(self, msg: str, status: int = _OK, category: str | None = None):
        """Queue a message for the FMI logger (passed on by the bridge after each call)."""
        if category is None:
            category = {1: "logStatusWarning", 3: "logStatusError", 4: "logStatusFatal"}.get(status, "logEvents")
        self.log_queue.append((int(status), category, str(msg)))

    def _error(self, msg: str):
        self.log(msg, _ERROR, "logStatusError")

    def _allowed(self, mask: int, fn: str) -> bool:
        if self.model is not None and self._mode & mask:
            return True
        if self.model is None:
            self._error(f"{fn}: the instance has no model (instantiation failed)")
        else:
            self._error(f"{fn}: illegal call sequence: not allowed in state {_STATE_NAMES[self._mode]}")
        return False

    def _fn(self, name: str) -> str:
        return f"fmi{self.FMI}{name}"

    # ------------------------------------------------------------------------------------------- life cycle
    def setup_experiment(self, tolerance_defined, tolerance, start_time, stop_time_defined, stop_time):
        """fmi2SetupExperiment (FMI 3.0 passes the same to :meth:`enter_initialization_mode`)."""
        try:
            if not self._allowed(INSTANTIATED, self._fn("SetupExperiment")):
                return
            self._set_experiment(start_time, stop_time if stop_time_defined else None,
                                 tolerance if tolerance_defined else None)
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('SetupExperiment')}: {e}")

    def _set_experiment(self, start_time, stop_time, tolerance):
        start = 0.0 if start_time is None else float(start_time)
        if not math.isfinite(start):
            raise GyrosimError(f"startTime = {start_time!r} is not allowed: a finite number in s")
        if stop_time is not None:
            stop_time = float(stop_time)
            if not (stop_time >= start):
                raise GyrosimError(f"stopTime = {stop_time!r} is not allowed: a number >= startTime = {start!r}")
        if tolerance is not None:
            tolerance = float(tolerance)
            if not (math.isfinite(tolerance) and tolerance > 0):
                raise GyrosimError(f"tolerance = {tolerance!r} is not allowed: a finite number > 0")
        self._experiment = (start, stop_time, tolerance)

    def enter_initialization_mode(self, *experiment):
        """Create the model of the experiment (start, stop, tolerance) and replay the values set so far.

        FMI 3.0 passes the experiment here: (toleranceDefined, tolerance, startTime, stopTimeDefined, stopTime).
        """
        try:
            if not self._allowed(INSTANTIATED, self._fn("EnterInitializationMode")):
                return
            if experiment:
                tol_def, tol, start, stop_def, stop = experiment
                self._set_experiment(start, stop if stop_def else None, tol if tol_def else None)
            start, stop, tol = self._experiment
            model = self._new_model(start, stop, tol)
            for name, value in self._pending.items():
                model.set(name, value, body=0)
            self.model = model
            self._mode = INITIALIZATION_MODE
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('EnterInitializationMode')}: {e}")

    def exit_initialization_mode(self):
        """Validate the parameters and the initial state (``Model.initialize``); Error keeps the mode."""
        try:
            if not self._allowed(INITIALIZATION_MODE, self._fn("ExitInitializationMode")):
                return
            self.model.initialize()
            self._mode = STEP_COMPLETE
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('ExitInitializationMode')}: {e}")

    def terminate(self):
        try:
            if self._allowed(STEP_COMPLETE | INITIALIZATION_MODE, self._fn("Terminate")):
                self._mode = TERMINATED
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('Terminate')}: {e}")

    def reset(self):
        """fmiXReset: back to the state right after instantiation (start values, no experiment)."""
        try:
            queue = self.log_queue
            self.__init__(**self._kwargs)
            self.log_queue[:0] = queue
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('Reset')}: {e}")

    def do_step(self, t: float, h: float) -> bool:
        """fmiXDoStep from ``t`` over ``h``; True when the step was taken."""
        m = self.model
        if self._mode == STEP_COMPLETE and h > 0.0 and abs(t - m.time) <= _TIME_TOL * max(1.0, abs(t)):
            try:
                m.step(h)
                return True
            except GyrosimError as e:
                self._error(f"{self._fn('DoStep')}: {e}")
                return False
        try:
            fn = self._fn("DoStep")
            if not self._allowed(STEP_COMPLETE, fn):
                return False
            if not (math.isfinite(h) and h > 0.0):
                self._error(f"{fn}: communicationStepSize = {h!r} is not allowed: a finite number > 0 in s")
                return False
            self._error(f"{fn}: expected currentCommunicationPoint = {m.time!r} s (the FMU's time) but was "
                        f"{t!r} s")
            return False
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('DoStep')}: {e}")
            return False

    # ------------------------------------------------------------------------------------------- values
    _SET_MASK_PARAMETER = INSTANTIATED | INITIALIZATION_MODE
    _SET_MASK_START = INSTANTIATED | INITIALIZATION_MODE
    _SET_MASK_INPUT = INSTANTIATED | INITIALIZATION_MODE | STEP_COMPLETE
    _GET_MASK = INITIALIZATION_MODE | STEP_COMPLETE | TERMINATED

    def _get(self, vrs, kind: str):
        n = len(vrs)
        nan = "" if kind == "String" else math.nan
        try:
            fn = self._fn("GetString" if kind == "String" else ("GetReal" if self.FMI == 2 else "GetFloat64"))
            if not self._allowed(self._GET_MASK, fn):
                return [nan] * n
            out = []
            row = None
            for vr in vrs:
                if vr == 0 and self.FMI == 3 and kind == "Real":
                    out.append(self.model.time)
                    continue
                v = self._by_vr.get(vr)
                if v is None or v.type != kind:
                    self._error(f"{fn}: no {kind} variable has valueReference {vr}")
                    out.append(nan)
                elif v.causality == "output":
                    if row is None:
                        row = self.model.outputs_array()[0]
                    out.append(float(row[self._out_index[v.name]]))
                else:
                    out.append(self.model.get(v.name, 0))
            return out
        except Exception as e:  # noqa: BLE001
            self._error(f"{fn}: {e}")
            return [nan] * n

    def _set(self, vrs, values, kind: str):
        fn = self._fn("SetString" if kind == "String" else ("SetReal" if self.FMI == 2 else "SetFloat64"))
        try:
            if self.model is None:
                self._allowed(0, fn)
                return
            if len(values) != len(vrs):
                self._error(f"{fn}: {len(vrs)} value references but {len(values)} values")
                return
            for vr, value in zip(vrs, values):
                v = self._by_vr.get(vr)
                if v is None or v.type != kind:
                    self._error(f"{fn}: no {kind} variable has valueReference {vr}")
                    continue
                if v.causality == "input":
                    mask = self._SET_MASK_INPUT
                elif v.causality == "parameter":
                    mask = self._SET_MASK_PARAMETER
                elif v.name in _DERIVED:
                    self._error(f"{fn}: {v.name} is a derived output (computed from the state); it cannot be "
                                "set")
                    continue
                else:
                    mask = self._SET_MASK_START
                if not self._mode & mask:
                    what = {"input": "input", "parameter": "fixed parameter"}.get(v.causality, "state start")
                    self._error(f"{fn}: the {what} {v.name} cannot be set in state {_STATE_NAMES[self._mode]}")
                    continue
                try:
                    self.model.set(v.name, value, body=0)
                except GyrosimError as e:
                    self._error(f"{fn}: {e}")
                    continue
                if self._mode == INSTANTIATED:
                    self._pending[v.name] = value
        except Exception as e:  # noqa: BLE001
            self._error(f"{fn}: {e}")

    def get_real(self, vrs):
        return self._get(vrs, "Real")

    def set_real(self, vrs, values):
        self._set(vrs, values, "Real")

    def get_string(self, vrs):
        return self._get(vrs, "String")

    def set_string(self, vrs, values):
        self._set(vrs, values, "String")

    # ------------------------------------------------------------------------------------------- FMU state
    def get_fmu_state(self):
        """The FMU state: pickled (format tag, experiment, pending values, whole model state)."""
        try:
            if self.model is None:
                self._allowed(0, self._fn("GetFMUstate"))
                return b""
            return pickle.dumps(("gyrosim-fmu-state-1", self._experiment, dict(self._pending),
                                 self.model.state_bytes()), protocol=pickle.HIGHEST_PROTOCOL)
        except Exception as e:  # noqa: BLE001
            self._error(f"{self._fn('GetFMUstate')}: {e}")
            return b""

    def set_fmu_state(self, state):
        fn = self._fn("SetFMUstate")
        try:
            if self.model is None:
                self._allowed(0, fn)
                return
            try:
                tag, experiment, pending, model_bytes = pickle.loads(bytes(state))
                if tag != "gyrosim-fmu-state-1":
                    raise ValueError(f"format {tag!r}")
            except Exception as e:  # noqa: BLE001
                self._error(f"{fn}: not an FMU state of this FMU ({type(e).__name__}: {e})")
                return
            self.model.set_state_bytes(model_bytes)
            self._experiment = experiment
            self._pending = pending
        except Exception as e:  # noqa: BLE001
            self._error(f"{fn}: {e}")

    # ------------------------------------------------------------------------------------------- fast path
    def _fast_info(self):
        """What the bridge needs to take plain doSteps itself, or None when they must come here.

        ``(cfunc address, method code, flags, addresses of y, p, hint, stats, status, max_step, tolerance,
        t_base, n, h, has stop time, stop time)``: one body, a kernel integrator, step mode, an initialised model
        whose state arrays stay where they are until the next call into Python (the bridge asks again after every
        call that may change them). ``GYROSIM_FMU_FAST=0`` turns the fast path off.
        """
        m = self.model
        if (m is None or self._mode != STEP_COMPLETE or m.n_bodies != 1 or m.integrator == "exact"
                or not m._initialized or m._state_dirty):
            return None
        address = _fast_address()
        if address is None:
            return None
        arrays = (m._y, m._p, m._hint, m._stats, m._status)
        if not all(a.flags.c_contiguous and a.flags.writeable for a in arrays):
            return None
        return (address, kernels.METHOD_CODES[m.integrator], int(m.scene.flags), m._y.ctypes.data,
                m._p.ctypes.data, m._hint.ctypes.data, m._stats.ctypes.data, m._status.ctypes.data,
                float(m.max_step), float(m.tolerance), float(m._t_base), int(m._n), float(m._h),
                int(m.stop_time is not None), float(m.stop_time if m.stop_time is not None else 0.0))

    def _sync_clock(self, t_base, n, h):
        """Take the clock the bridge kept over its fast steps (and forget the cached outputs)."""
        m = self.model
        m._t_base, m._n, m._h = float(t_base), int(n), float(h)
        m._out = None


_FAST = []


def _fast_address():
    """Address of the fast-path cfunc (compiled on first use), or None without numba or with GYROSIM_FMU_FAST=0."""
    if os.environ.get("GYROSIM_FMU_FAST", "1") == "0":
        return None
    if not _FAST:
        address = None
        from ..core._jit import HAVE_NUMBA

        if HAVE_NUMBA:
            try:
                from .fast import advance_one

                address = int(advance_one.address)
            except Exception:  # noqa: BLE001 - no fast path is slower, never wrong
                address = None
        _FAST.append(address)
    return _FAST[0]


class Fmi2Slave(_Core):
    """FMI 2.0 co-simulation facade, called by the FMU's C bridge."""

    FMI = 2


class Fmi3Slave(_Core):
    """FMI 3.0 co-simulation facade, called by the FMU's C bridge."""

    FMI = 3
