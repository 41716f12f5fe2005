"""One chunk of a sweep: its samples as bodies of one Model, run in compiled calls of the engine.

:func:`run_chunk` is the unit of work, the same in the process and as a Dask task (a worker imports this module;
it imports neither dask nor pyarrow). It returns the chunk's columns as numpy arrays in sample order.

Per sample (row):

* the varied values (state starts as ``<name>_start``);
* the final value of every output (:data:`gyrosim.model.OUTPUT_NAMES`) at ``stop_time``; NaN for a sample that
  blew up;
* ``max_energy_drift``: the largest ``|energy_error|`` over the output points, relative to the start energy's
  scale ``S0 = T0 + |mass*g*cm_distance|`` (``T0`` the start's kinetic energy; the health monitor's scale);
  ``energy_error`` is the work-energy balance, so damping and input torques do not count as drift;
* ``max_L_drift``: the largest ``| |L(t)| - |L(0)| |`` over the output points, relative to
  ``Ls = max(|L(0)|, sqrt(2 max(I) |mass*g*cm_distance|))`` (the monitor's scale). |L| is conserved where the
  body is torque-free; under gravity or input torques this is its physical change, not an error;
  (a scale of 0, a body at rest with no gravity, gives the absolute value);
* ``blew_up``: the engine's health monitor (a non-finite state, or a drift beyond ``max_drift``) stopped the
  sample; ``blew_up_time``: the output point (s) at which it was found (NaN when it ran to the end). The drifts of a
  sample that blew up are those of the output points before that.
* ``lyapunov`` (with ``--lyapunov``): the largest Lyapunov exponent of the sample's run (1/s, renormalised
  neighbours on the sweep's output grid, :func:`gyrosim.analysis.chaos.lyapunov`; NaN where it blew up, -inf where
  the neighbour met the sample in the same state, as a mass coming to rest on an impact stop): a second
  run of the chunk's samples, each with its neighbour, so the other columns keep their bits.
"""

from __future__ import annotations

import numpy as np

from ..model import Model
from .interrupt import check as check_interrupt
from .sampling import draw
from .spec import MODEL_WIDE, SweepSpec, column_name

__all__ = ["run_chunk", "result_columns", "BLOCK_VALUES"]

#: Output values (doubles) held per compiled call: the run goes over the time grid in blocks of this size
BLOCK_VALUES = 1 << 22
#: Renormalisations of a sample's neighbour in a run (the ``lyapunov`` column): each is one engine call over the
#: chunk, and a growth beyond 1e3 in one halves the intervals after it (gyrosim.analysis.chaos.GROWTH_LIMIT)
LYAPUNOV_INTERVALS = 200
_REPLICAS: dict = {}


def result_columns(spec: SweepSpec) -> list[tuple[str, str]]:
    """(column, kind) in file order: kind is ``int``, ``float``, ``str`` or ``bool``."""
    cols = [("sample", "int")]
    states = set(spec.scene.state_names())
    for name, dist in spec.vary:
        cols.append((column_name(name, states), "str" if dist.kind == "choice" and isinstance(dist.args[0], str)
                     else "float"))
    cols += [(o, "float") for o in _output_names(spec.scene)]
    cols += [("max_energy_drift", "float"), ("max_L_drift", "float"), ("blew_up", "bool"),
             ("blew_up_time", "float")]
    if spec.lyapunov:
        cols.append(("lyapunov", "float"))
    return cols


def _output_names(scene) -> list[str]:
    return scene.output_names()


def _replicated(scene, k: int):
    """``scene`` with its one body replicated ``k`` times, or ``k`` copies of a tree (cached per scene object and
    k)."""
    key = (id(scene), k)
    hit = _REPLICAS.get(key)
    if hit is None or hit[0] is not scene:
        if len(_REPLICAS) > 16:
            _REPLICAS.clear()
        hit = (scene, scene.replicated(k))
        _REPLICAS[key] = hit
    return hit[1]


def _check_version(spec: SweepSpec) -> None:
    import gyrosim

    if spec.version and spec.version != gyrosim.__version__:
        from ..errors import GyrosimError

        raise GyrosimError(f"this worker has gyrosim {gyrosim.__version__}, the sweep was made with "
                           f"{spec.version}: install the same version on every worker")


_SPECS: dict = {}


def _same_spec(spec: SweepSpec) -> SweepSpec:
    """The first spec equal to ``spec`` that this process saw: a Dask worker unpickles a new copy for every task,
    and the scene caches (replicas, the Model's layout) go by the scene object."""
    key = spec.token()
    hit = _SPECS.get(key)
    if hit is None:
        if len(_SPECS) > 16:
            _SPECS.clear()
        _SPECS[key] = hit = spec
    return hit


def run_chunk(spec: SweepSpec, k: int) -> dict:
    """Run chunk ``k`` of ``spec``: {column: array} in sample order (see the module docstring)."""
    _check_version(spec)
    spec = _same_spec(spec)
    a, b = spec.chunk_bounds(k)
    n = b - a
    draws = draw(spec, a, b)
    wide = [name for name in spec.varied_names if name in MODEL_WIDE]
    if wide:  # one Model per combination of the varied model-wide values
        keys = list(zip(*(draws[w].tolist() for w in wide)))
        groups: dict = {}
        for i, key in enumerate(keys):
            groups.setdefault(key, []).append(i)
        parts = [(np.array(idx), dict(zip(wide, key))) for key, idx in groups.items()]
    else:
        parts = [(np.arange(n), {})]
    res = {c: (np.empty(n, dtype=np.int64) if kind == "int" else np.empty(n, dtype=bool) if kind == "bool"
               else np.empty(n, dtype=object) if kind == "str" else np.empty(n)) for c, kind in result_columns(spec)}
    res["sample"][:] = np.arange(a, b)
    states = set(spec.scene.state_names())
    for name in spec.varied_names:
        res[column_name(name, states)][:] = draws[name]
    for idx, wide_values in parts:
        sub = {name: draws[name][idx] for name in spec.varied_names if name not in MODEL_WIDE}
        out = _run_group(spec, len(idx), sub, wide_values)
        for c, v in out.items():
            res[c][idx] = v
    return res


def _model_for(spec: SweepSpec, k: int, per_body: dict, wide: dict) -> Model:
    model = Model(_replicated(spec.scene, k), stop_time=spec.stop_time)
    values = {}
    for name, value in list(spec.fixed) + list(wide.items()):
        if name == "tolerance":
            model.set_tolerance(float(value))
        else:
            values[name] = value
    values.update(per_body)   # one value per copy
    model.set_values(values)   # checked together: the order of --set and --vary does not matter
    return model


def _drive(spec: SweepSpec, model: Model, names: list, drifts, s_energy: np.ndarray, s_L: np.ndarray, **kw) -> dict:
    """Run ``model``'s k samples over the sweep's grid in blocks of compiled calls: the final outputs (NaN for a
    sample that blew up), the largest drifts (``drifts(traj) -> (energy, L)`` per sample, over the output points
    before a blow-up) relative to the scales, and where each sample blew up."""
    k = len(s_energy)
    dt, n = spec.output_interval, spec.n_intervals
    block = max(1, BLOCK_VALUES // (len(names) * k))
    status = np.zeros(k, dtype=np.int32)
    failed_at = np.zeros(k, dtype=np.int64)
    alive = np.ones(k, dtype=bool)
    max_e = np.zeros(k)
    max_l = np.zeros(k)
    done = 0
    while done < n:
        m = min(block, n - done)
        traj = model.trajectory(dt, m, status=status, **kw)
        check_interrupt()  # a Ctrl-C in the sweep's process: acted on after each engine call
        e, dl = drifts(traj)
        if alive.all():
            np.fmax(max_e, e, out=max_e)
            np.fmax(max_l, dl, out=max_l)
        else:  # a sample that failed before is not looked at again
            max_e[alive] = np.fmax(max_e[alive], e[alive])
            max_l[alive] = np.fmax(max_l[alive], dl[alive])
        new = alive & (status > 0)
        if new.any():
            failed_at[new] = done + status[new]
            alive &= ~new
        done += m
    final = model.outputs_array()
    final[~alive] = np.nan
    out = {o: final[:, j] for j, o in enumerate(names)}
    s_energy[~(s_energy > 0)] = 1.0
    s_L[~(s_L > 0)] = 1.0
    out["max_energy_drift"] = max_e / s_energy
    out["max_L_drift"] = max_l / s_L
    out["blew_up"] = ~alive
    out["blew_up_time"] = np.where(alive, np.nan, failed_at * dt)
    return out


def _run_group(spec: SweepSpec, k: int, per_body: dict, wide: dict) -> dict:
    """``k`` samples sharing the model-wide values ``wide``, with the per-body values ``per_body`` (and their
    ``lyapunov`` column when the spec asks for it): k systems of one model (k bodies of a one-body scene, k copies
    of a tree), the drifts measured as the model's health monitor measures them (``Model.drift_measure``)."""
    model = _model_for(spec, k, per_body, wide)
    out0 = model.outputs_array()  # validates and starts the state (t = 0)
    s_energy, s_L, drifts, kw = model.drift_measure(out0)
    out = _drive(spec, model, _output_names(spec.scene), drifts, s_energy, s_L, **kw)
    if spec.lyapunov:
        from ..analysis.chaos import lyapunov_copies

        # 200 renormalisations a run: a call of the engine over many copies costs milliseconds however short
        res = lyapunov_copies(_model_for(spec, k, per_body, wide), time=spec.stop_time,
                              output_interval=spec.output_interval, interval=spec.stop_time / LYAPUNOV_INTERVALS,
                              period=False, keep_going=True, progress=lambda *_: check_interrupt())
        out["lyapunov"] = np.atleast_1d(res.exponent)
    return out
