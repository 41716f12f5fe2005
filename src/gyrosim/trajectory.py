"""``gyrosim.simulate``: a whole trajectory in one call of the engine, in FMPy's habits (``fmpy.simulate_fmu``).

The output grid is produced inside the C engine (no Python per output point): fixed-step integrators and ``exact``
advance from output point to output point (the bits of a loop of ``Model.step``); ``adaptive`` and ``dop853`` take
the steps their error control chooses and interpolate the output points (dense output).
"""

from __future__ import annotations

import math

import numpy as np

from .core import _engine
from .errors import ConfigError, IntegrationError
from .model import Model
from .scene import EMBEDDED_SCENES, Scene, did_you_mean, load_scene

__all__ = ["simulate", "Run", "field_names", "output_intervals"]

def field_names(model: Model) -> list[str]:
    """The output names of ``model``: ``<body>.<name>`` in multi-body scenes, the bare names otherwise."""
    return model.scene.output_names()


def output_intervals(span: float, dt: float, end: float) -> int:
    """Output intervals of ``dt`` s in ``span`` s ending at ``end`` s: ``span / dt`` rounded when it is whole to
    1e-9 of ``max(1, |end|)``, else the whole intervals that fit (at least 1)."""
    n = max(1, round(span / dt))
    if abs(n * dt - span) > 1e-9 * max(1.0, abs(end)):
        n = math.floor(span / dt + 1e-9)
    return n


def _apply_start_values(model: Model, start_values: dict) -> None:
    values = {}
    for name, value in start_values.items():
        key = str(name)  # a full name: <body>.<name> in a scene of several bodies, whichever kernel runs it
        var = model.variables.get(key) or model.variables.get(key.partition(".")[2])
        if var is not None and var.type == "Real" and isinstance(value, str):
            try:
                value = float(value)
            except ValueError:
                raise ConfigError(str(name), value, f"a real number in {var.unit or '1'}") from None
        values[key] = value
    model.set_values(values)  # checked together: the order of --set's does not matter


def apply_overrides(model, start_values=None, integrator=None, max_step=None) -> None:
    """A run's overrides on a fresh model, as simulate takes them: start values (and parameters) by name, then the
    integrator and max_step."""
    if start_values:
        _apply_start_values(model, dict(start_values))
    if integrator is not None:
        model.set("integrator", integrator)
    if max_step is not None:
        model.set("max_step", max_step)


def simulate(scene=None, *, start_values=None, start_time=0.0, stop_time=None, output_interval=None,
             integrator=None, max_step=None, relative_tolerance=None, output=None, input=None) -> np.ndarray:
    """Simulate a scene and return its outputs on a regular grid, as ``fmpy.simulate_fmu`` does.

    Parameters
    ----------
    scene : str, Path, Scene or None
        Embedded scene name, TOML path or :class:`~gyrosim.scene.Scene`; ``None`` is the full model.
    start_values : dict, optional
        Parameters, start states (``q_*``, ``omega_*``), inputs and ``integrator`` by variable name
        (``<body>.<name>`` for one body of a multi-body scene; a bare name sets every body).
    start_time, stop_time : float
        s; ``stop_time`` defaults to the scene's.
    output_interval : float, optional
        s; defaults to the scene's.
    integrator, max_step, relative_tolerance : optional
        Override the scene's (and ``start_values``); the tolerance drives ``adaptive`` and ``dop853``.
    output : list of str, optional
        The output fields to return (default: every output).
    input : numpy structured array or InputSignal, optional
        Time-varying inputs, as ``fmpy.simulate_fmu(input=...)`` takes them: field ``time`` (s, non-decreasing)
        then one field per input (``tau_x``; ``<body>.tau_x`` with several bodies; ``<body>.motor_torque`` in a
        tree); :func:`gyrosim.inputs.read_input_csv` reads one from FMPy's CSV format. At the start of every output
        interval the inputs take their values at that interval's start time ``start_time + k*output_interval``
        (linear between rows, held before the first and after the last, the later row at a step:
        :mod:`gyrosim.inputs`) and are held over the interval, as FMPy does for a co-simulation FMU (set the
        inputs, ``doStep``). Inputs not in the array keep their start values.

    Returns
    -------
    numpy structured array
        Field ``time`` (s) and one float64 field per output, one row per output point ``start_time + k *
        output_interval`` up to ``stop_time``.

    Raises
    ------
    ConfigError
        An unknown name or a value that is not allowed (an input that is not one of the scene's, a time going
        backwards, ...).
    IntegrationError
        The run blew up (``error.rows`` holds the structured rows before the failing interval).

    Notes
    -----
    A run without start values or inputs is prepared once per scene object and arguments and copied on the next
    calls; a one-body such run that went through keeps its engine call, and the next call with the same scene
    object and arguments runs it again on copies of its start state (the same rows, without the set-up's checks,
    which it passed). A :class:`~gyrosim.scene.Scene` is frozen: another parameter is another scene object.

    Examples
    --------
    >>> r = simulate("free_body", stop_time=1.0, output_interval=0.1, output=["omega_x"])
    >>> r.dtype.names, len(r)
    (('time', 'omega_x'), 11)
    """
    key, ready = _kept(_READY, scene, start_values, start_time, stop_time, output_interval, integrator, max_step,
                       relative_tolerance, output, input)
    if ready is not None:  # the run's engine call again, on copies of its start state
        head, tail, shape, dtype = ready[1:]
        res = np.empty(shape)
        if not _engine.trajectory_select(*head, res, *tail, False):
            return np.frombuffer(res, dtype)
    args = dict(start_values=start_values, start_time=start_time, stop_time=stop_time,
                output_interval=output_interval, integrator=integrator, max_step=max_step,
                relative_tolerance=relative_tolerance, output=output, input=input)
    run = Run(scene, **args)
    try:
        model = run.model
        if run.input is not None:
            out = run._advance_with_input(0, run.n)
        else:  # the model is dropped when the run fails: its state before the call not kept
            # a lone body's result rows written once by the engine (pack's bits)
            if model.ROWS_DIRECT and model.n_bodies == 1 and len(run._columns):
                keep = key is not None
                res, call = model._trajectory_select(run.dt, run.n, run._columns, run.t0, run.angles,
                                                     run.momentum, ready=keep)
                if res is not None:
                    if keep:
                        if len(_READY) > 256:
                            _READY.clear()
                        _READY[key] = (run.scene, *call, res.shape, run.dtype)
                    return np.frombuffer(res, run.dtype)
                run = Run(scene, **args)  # it failed: again with whole rows, for the error and the rows before it
                model = run.model
            out = model._trajectory(run.dt, run.n, run.angles, run.momentum, None, False)
    except IntegrationError as e:
        e.rows = run.pack(e.rows)
        raise
    return run.pack(out)


class Run:
    """A prepared run of :func:`simulate` (same arguments): the model set up, the grid and the output selection.

    ``Run(...).chunks(k)`` yields the result in blocks of at most ``k`` output intervals, one engine call each
    (the ``gyrosim simulate`` command writes them to CSV as they come, in bounded memory).

    Attributes
    ----------
    model : Model
        The model, with the start values applied.
    t0, dt : float
        Start time and output interval, s.
    n : int
        Output intervals: the result has ``n + 1`` rows.
    names : list of str
        The output fields, in order (the result's fields are ``time`` and these).
    input : InputSignal or None
        The time-varying inputs (checked against the scene's inputs), applied at the start of every output interval.
    """

    def __init__(self, scene=None, *, start_values=None, start_time=0.0, stop_time=None, output_interval=None,
                 integrator=None, max_step=None, relative_tolerance=None, output=None, input=None):
        key, hit = _kept(_PREPARED, scene, start_values, start_time, stop_time, output_interval, integrator,
                         max_step, relative_tolerance, output, input)
        if hit is not None:
            self.__dict__.update(hit[1])
            self.model = hit[2]._replica()
            return
        self._prepare(scene, start_values, start_time, stop_time, output_interval, integrator, max_step,
                      relative_tolerance, output, input)
        if key is not None and self.model.n_bodies <= 64 and self.model._replicable():  # a few kB kept
            if len(_PREPARED) > 256:
                _PREPARED.clear()
            attrs = dict(self.__dict__)
            _PREPARED[key] = (self.scene, attrs, attrs.pop("model"))
            self.model = self.model._replica()  # the kept one is never run

    def _prepare(self, scene, start_values, start_time, stop_time, output_interval, integrator, max_step,
                 relative_tolerance, output, input):
        sc = load_scene(scene)
        t0 = float(start_time)
        if not math.isfinite(t0):
            raise ConfigError("start_time", start_time, "a finite number in s")
        stop = sc.stop_time if stop_time is None else float(stop_time)
        dt = sc.output_interval if output_interval is None else float(output_interval)
        if not (math.isfinite(dt) and dt > 0):
            raise ConfigError("output_interval", output_interval, "a finite number > 0 in s")
        if not (math.isfinite(stop) and stop > t0):
            raise ConfigError("stop_time", stop_time, f"a finite number > start_time = {t0!r} s")
        self.scene = sc
        self.model = model = Model(sc, start_time=t0, stop_time=stop, tolerance=relative_tolerance)
        apply_overrides(model, start_values, integrator, max_step)
        self.t0, self.dt, self.stop_time = t0, dt, stop
        self.n = output_intervals(stop - t0, dt, stop)
        (self.names, self._columns, self.dtype, self.angles,
         self.momentum) = _selection(sc, None if output is None else tuple(output))
        self.input = None
        if input is not None:
            from .inputs import InputSignal

            self.input = input if isinstance(input, InputSignal) else InputSignal(input)
            self._setters = self.input.check_against(model)

    def _advance_with_input(self, k0: int, m: int) -> np.ndarray:
        """Advance ``m`` output intervals from output point ``k0`` (the model's current time), the inputs set at the
        start of each interval to their values at ``t0 + k*dt`` and held over it: the engine's rows
        ``(m + 1, n_bodies, n_out)``, row 0 the current outputs (as :meth:`Model.trajectory` returns them).

        Intervals with the same input values go to the engine in one trajectory call where that gives the bits of a
        step per interval (``Model.trajectory_is_steps``: the fixed-step methods and ``exact``); ``adaptive`` and
        ``dop853`` take one step per interval (what an FMU's doStep does), one body or a tree."""
        model, dt = self.model, self.dt
        times = self.t0 + np.arange(k0, k0 + m, dtype=np.float64) * dt  # FMPy: start_time + n_steps*interval
        table = self.input.table(times)
        setters = self._setters
        model_set = model.set

        def apply(row):
            for (_, var, body), x in zip(setters, row.tolist()):
                model_set(var, x, body)

        if m == 0:
            return model.outputs_array()[None]
        apply(table[0])
        rows = None
        grouped = model.trajectory_is_steps_for(dt)
        k = 0
        try:
            if grouped:
                bits = table.view(np.uint64)
                changes = np.flatnonzero(np.any(bits[1:] != bits[:-1], axis=1)) + 1  # intervals whose inputs change
                ends = np.append(changes, m)
                for e in ends.tolist():
                    r = e - k
                    if k:
                        apply(table[k])
                    block = model.trajectory(dt, r, angles=self.angles, momentum=self.momentum)
                    if rows is None:
                        rows = np.empty((m + 1,) + block.shape[1:])
                        rows[0] = block[0]
                    rows[k + 1:k + r + 1] = block[1:]
                    k = e
            else:
                first = model.outputs_array()
                rows = np.empty((m + 1,) + first.shape)
                rows[0] = first
                while k < m:
                    if k:
                        apply(table[k])
                    model.step(dt)
                    rows[k + 1] = model._outputs_array()
                    k += 1
        except IntegrationError as e:
            done = np.asarray(e.rows) if getattr(e, "rows", None) is not None else None
            if rows is None:
                e.rows = done if done is not None else np.empty((0,) + model.outputs_array().shape)
            elif grouped and done is not None:
                e.rows = np.concatenate([rows[:k], done])
            else:
                e.rows = rows[:k + 1].copy()
            raise
        return rows

    def pack(self, block: np.ndarray, k0: int = 0) -> np.ndarray:
        """Engine rows ``(rows, n_bodies, 15)`` of output points ``k0, k0 + 1, ...`` -> structured result rows."""
        res = np.empty((block.shape[0], 1 + len(self._columns)))
        _engine.pack(block, self._columns, self.t0, self.dt, res)
        if k0:
            res[:, 0] = self.t0 + (np.arange(block.shape[0]) + k0) * self.dt
        return np.frombuffer(res, self.dtype)  # res.view(self.dtype).reshape(-1), without view's checks of fields

    def chunks(self, size: int):
        """Yield the result in blocks: the first holds output points ``0..m``, the next ``m+1..``, ... (``size``
        output intervals per engine call, at least 1).

        Raises
        ------
        IntegrationError
            With ``error.rows``: the structured rows computed in the failing call before the failing interval
            (those not yielded yet).
        """
        size = max(1, int(size))
        done = 0
        while done < self.n:
            m = min(size, self.n - done)
            try:
                if self.input is None:
                    block = self.model.trajectory(self.dt, m, angles=self.angles, momentum=self.momentum)
                else:
                    block = self._advance_with_input(done, m)
            except IntegrationError as e:
                rows = np.asarray(e.rows)
                e.rows = self.pack(rows, done) if done == 0 else self.pack(rows[1:], done + 1)
                raise
            yield self.pack(block, done) if done == 0 else self.pack(block[1:], done + 1)
            done += m


def _kept(cache: dict, scene, start_values, start_time, stop_time, output_interval, integrator, max_step,
          relative_tolerance, output, input) -> tuple:
    """``(key, entry)`` of a run in :data:`_PREPARED` or :data:`_READY`: the key of a run with no start values or
    inputs of a Scene or an embedded scene (the scene object's identity and the arguments), None for any other run or
    an argument that is not hashable; the entry kept under it for the same scene object, or None."""
    if not (input is None and (start_values is None or (type(start_values) is dict and not start_values))
            and (output is None or type(output) in (list, tuple))
            and (isinstance(scene, Scene) or (type(scene) is str and scene in EMBEDDED_SCENES))):
        return None, None
    sc = load_scene(scene)  # frozen, and the same object for an embedded name
    key = (id(sc), start_time, stop_time, output_interval, integrator, max_step, relative_tolerance,
           None if output is None else tuple(output))
    try:
        entry = cache.get(key)
    except TypeError:  # an argument that is not hashable: not kept
        return None, None
    return key, entry if entry is not None and entry[0] is sc else None


#: One-body runs of :func:`simulate` with no start values or inputs that went through, by scene and arguments:
#: (scene, the engine call's arguments before and after its result array, copied before it ran, the result's shape
#: and dtype). The same call again, on copies of that start state (``keep_state=False``), gives the same rows: the
#: same scene object and arguments passed the same checks and built the same model (as :data:`_PREPARED`).
_READY: dict = {}

#: Prepared runs of the one-body engine without start values or inputs, by scene and arguments: (scene, the Run's
#: attributes but the model, a model to replicate); a hit gives the attributes and a replica of the model (the
#: arguments equal, the same checks passed and the same model built: a run's set-up is a few copies).
_PREPARED: dict = {}

_SELECTIONS: dict = {}


def _selection(sc, output: tuple | None):
    """The picked output names, their columns in the engine's rows, the result dtype and whether angles and
    momentum are needed; cached per scene and selection."""
    key = (id(sc), output)
    hit = _SELECTIONS.get(key)
    if hit is not None and hit[0] is sc:
        return hit[1]
    names = sc.output_names()
    if output is None:
        picked = names
    else:
        picked = list(output)
        known = set(names)
        for o in picked:
            if o not in known:
                raise ConfigError("output", o, f"an output of scene {sc.name!r}{did_you_mean(o, names)}: "
                                  + ", ".join(names[:20]))
    index = {name: i for i, name in enumerate(names)}
    columns = np.array([index[o] for o in picked], dtype=np.int64)
    dtype = np.dtype([("time", np.float64)] + [(o, np.float64) for o in picked])
    bare = {o.rsplit(".", 1)[-1] for o in picked}
    value = (picked, columns, dtype, bool(bare & {"phi", "theta", "psi"}),
             bool(bare & {"L_x", "L_y", "L_z", "energy", "energy_error"}))
    if len(_SELECTIONS) > 256:
        _SELECTIONS.clear()
    _SELECTIONS[key] = (sc, value)
    return value
