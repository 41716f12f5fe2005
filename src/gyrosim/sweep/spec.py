"""The sweep specification: distributions, the ``[sweep]`` table of a scene file, merging with the command line and
every check that runs before any work starts.

A sweep replicates the one body of a scene once per sample; each sample sets some variables from distributions
(``vary``) and others to fixed values (``set``). Names are the model variables of fmu/README.md that a user may
set: parameters (``I1``, ``mass``, ``integrator``, ``max_step``, ...), inputs (``tau_x``, ...) and state starts
(``q_*``, ``omega_*``), plus ``tolerance`` (the tolerance of ``adaptive`` and ``dop853``).

Distributions (``DIST``)::

    uniform(lo,hi)          lo + (hi - lo) u                       lo <= hi
    normal(mean,std)        mean + std * Phi^-1(u)                 std >= 0
    lognormal(mean,sigma)   exp(mean + sigma * Phi^-1(u))          sigma >= 0 (mean, sigma of log(x), as numpy)
    choice(a,b,...)         one of the values, equally likely      strings only for integrator
    linspace(lo,hi)         sample i of N: lo + (hi - lo) i/(N-1)  lo <= hi; a grid over the samples

``u`` is the sample's counter-based uniform draw (:mod:`gyrosim.sweep.sampling`): it depends on the seed, the
variable's name and the sample index only.
"""

from __future__ import annotations

import hashlib
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core import _engine
from ..core.inertia import check_principal_moments
from ..errors import ConfigError
from ..kernel_body import STATE_NAMES
from ..ranges import POSITIVE
from ..scene import INTEGRATORS, Scene, did_you_mean, load_scene, scene_from_dict

__all__ = ["Dist", "SweepSpec", "parse_dist", "build_spec", "load_sweep_scene", "DISTRIBUTIONS",
           "MODEL_WIDE", "column_name"]

DISTRIBUTIONS = ("uniform", "normal", "lognormal", "choice", "linspace")
_FORMS = "uniform(lo,hi), normal(mean,std), lognormal(mean,sigma), choice(a,b,...) or linspace(lo,hi)"
#: Names that hold for a whole Model (one value per compiled call): samples are grouped by them.
MODEL_WIDE = ("integrator", "max_step", "max_drift", "tolerance")
#: The keys of a scene file's [sweep] table.
SWEEP_KEYS = ("samples", "seed", "chunk_size", "stop_time", "output_interval", "integrator", "max_step", "vary", "set",
              "lyapunov")
#: The most samples a sweep takes (the command line, a scene's [sweep] table, build_spec): a Parquet row each
#: (hundreds of bytes), so 1e8 is tens of GB of results and hours of work; beyond it a sweep's book-keeping alone
#: fills the memory (1e12 samples reached 10 GB in 25 s before the first chunk ran).
MAX_SAMPLES = 10 ** 8
#: Default samples per chunk (one compiled call of the engine, one Parquet file, one Dask task).
DEFAULT_CHUNK = 2000


#: The bare names of the joints' coordinates (``<body>.<name>``), for a column named without its scene: state starts
_TREE_STATES = STATE_NAMES + ("angle", "rate", "r_x", "r_y", "r_z", "v_x", "v_y", "v_z", "displacement", "velocity",
                              "orbit_anomaly")


def column_name(name: str, states=None) -> str:
    """The Parquet column of a varied variable: ``<name>_start`` for a state start (``omega_x_start``,
    ``rotor.rate_start``, ``displacement_start``), so that it never shares a name with the final output.

    ``states`` is the scene's :meth:`~gyrosim.scene.Scene.state_names` (every joint's coordinates, whatever the
    joint); without it, the bare names of today's joints decide."""
    if states is not None:
        return f"{name}_start" if name in states else name
    return f"{name}_start" if name.rpartition(".")[2] in _TREE_STATES else name


def _rule(var) -> tuple[str, object]:
    """What a value of the variable ``var`` (a :class:`gyrosim.model.Variable`) must be: its range (the model's,
    a scene parameter's from its scene file): (text, vectorised predicate on a float array)."""
    rng = var.range
    return rng.text(var.unit or "1"), rng.contains


@dataclass(frozen=True)
class Dist:
    """A parsed distribution: ``kind`` (one of :data:`DISTRIBUTIONS`) and its ``args`` (floats, or for ``choice``
    floats or strings)."""

    kind: str
    args: tuple

    @property
    def text(self) -> str:
        """The canonical text, e.g. ``uniform(1.0, 2.0)``."""
        return f"{self.kind}({', '.join(repr(a) if isinstance(a, str) else repr(float(a)) for a in self.args)})"

    def values(self, u: np.ndarray, index: np.ndarray, samples: int) -> np.ndarray:
        """The values for uniforms ``u`` in (0, 1) of samples ``index`` (of ``samples``)."""
        from scipy.special import ndtri

        k = self.kind
        if k == "uniform":
            lo, hi = self.args
            return lo + (hi - lo) * u
        if k == "normal":
            mean, std = self.args
            return mean + std * ndtri(u)
        if k == "lognormal":
            mean, sigma = self.args
            with np.errstate(over="ignore"):
                return np.exp(mean + sigma * ndtri(u))
        if k == "choice":
            j = np.minimum((u * len(self.args)).astype(np.int64), len(self.args) - 1)
            vals = np.array(self.args, dtype=object if isinstance(self.args[0], str) else float)
            return vals[j]
        lo, hi = self.args  # linspace
        t = index / (samples - 1) if samples > 1 else np.zeros(len(index))
        return lo * (1.0 - t) + hi * t

    @property
    def uses_draws(self) -> bool:
        return self.kind != "linspace"


_DIST_RE = re.compile(r"^\s*([A-Za-z_]\w*)\s*\((.*)\)\s*$", re.S)


def _number(text: str, what: str, field: str, dist: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise ConfigError(field, dist, f"{what} as a number (got {text.strip()!r})") from None
    if not math.isfinite(v):
        raise ConfigError(field, dist, f"{what} as a finite number (got {text.strip()!r})")
    return v


def parse_dist(text: str, name: str, *, string: bool = False, unit: str = "1", flag: str = "--vary") -> Dist:
    """Parse ``DIST`` for variable ``name`` (``string``: the variable takes strings, as ``integrator``).

    Raises
    ------
    ConfigError
        Naming ``--vary NAME``, the text and the allowed forms: an unknown distribution (with a "did you mean"),
        a wrong number of arguments, a non-number, ``lo > hi``, a negative ``std`` or ``sigma``, an empty or
        mistyped ``choice``.
    """
    field = f"{flag} {name}"
    if not isinstance(text, str):
        raise ConfigError(field, text, f"a distribution written as text: {_FORMS}")
    m = _DIST_RE.match(text)
    if not m:
        raise ConfigError(field, text, f"a distribution: {_FORMS}")
    kind, body = m.group(1), m.group(2)
    if kind not in DISTRIBUTIONS:
        raise ConfigError(field, text, f"a distribution: {_FORMS}{did_you_mean(kind, DISTRIBUTIONS)}")
    parts = [p.strip() for p in body.split(",")] if body.strip() else []
    if kind == "choice":
        if not parts or any(not p for p in parts):
            raise ConfigError(field, text, "choice(a,b,...) with at least one value and no empty ones")
        vals = [p[1:-1] if len(p) >= 2 and p[0] == p[-1] and p[0] in "'\"" else p for p in parts]
        if string:
            for v in vals:
                if v not in INTEGRATORS:
                    raise ConfigError(field, text, f"a choice of integrators: one of {', '.join(INTEGRATORS)}; "
                                      f"{v!r} is not one{did_you_mean(v, INTEGRATORS)}")
            return Dist(kind, tuple(vals))
        return Dist(kind, tuple(_number(v, f"choice values in {unit}", field, text) for v in vals))
    if string:
        raise ConfigError(field, text, f"choice(a,b,...) of names: {name} takes strings "
                          f"({', '.join(INTEGRATORS)})")
    names = {"uniform": ("lo", "hi"), "normal": ("mean", "std"), "lognormal": ("mean", "sigma"),
             "linspace": ("lo", "hi")}[kind]
    if len(parts) != 2:
        raise ConfigError(field, text, f"{kind}({names[0]},{names[1]}) with 2 numbers, got {len(parts)}")
    a, b = (_number(p, f"{n}", field, text) for p, n in zip(parts, names))
    if kind in ("uniform", "linspace") and a > b:
        raise ConfigError(field, text, f"{kind}(lo,hi) with lo <= hi (here lo = {a!r} > hi = {b!r}; swap them)")
    if kind in ("normal", "lognormal") and b < 0:
        raise ConfigError(field, text, f"{kind}({names[0]},{names[1]}) with {names[1]} >= 0 (got {b!r})")
    return Dist(kind, (a, b))


@dataclass(frozen=True)
class SweepSpec:
    """Everything that determines a sweep's rows (picklable: it is what a Dask task receives).

    Attributes
    ----------
    scene : Scene
        A one-body scene; the sweep replicates its body once per sample.
    samples, seed, chunk_size : int
    vary : tuple of (name, Dist)
        In the order given (the order of the columns).
    fixed : tuple of (name, value)
        Values set for every sample (``--set``, ``--integrator``, ``--max-step``).
    stop_time, output_interval : float
        s; drifts are taken over the output points ``k * output_interval``, ``k = 0..n_intervals``.
    version : str
        gyrosim's version (a worker with another version refuses the task).
    lyapunov : bool
        Add the column ``lyapunov``: each sample's largest Lyapunov exponent (1/s).
    """

    scene: Scene
    samples: int
    seed: int
    vary: tuple
    fixed: tuple
    stop_time: float
    output_interval: float
    n_intervals: int
    chunk_size: int
    version: str = field(default="")
    lyapunov: bool = False

    @property
    def n_chunks(self) -> int:
        return -(-self.samples // self.chunk_size)

    def chunk_bounds(self, k: int) -> tuple[int, int]:
        """Samples ``[a, b)`` of chunk ``k``."""
        a = k * self.chunk_size
        return a, min(self.samples, a + self.chunk_size)

    def spec_dict(self) -> dict:
        """The spec as JSON-able data (Parquet metadata ``gyrosim.spec``); chunk_size is not part of it: a sample's
        row does not depend on it."""
        d = {"samples": self.samples, "seed": self.seed, "vary": {n: d.text for n, d in self.vary},
             "set": {n: v for n, v in self.fixed}, "stop_time": self.stop_time,
             "output_interval": self.output_interval, "n_intervals": self.n_intervals}
        if self.lyapunov:  # only when asked: a sweep without the column keeps its manifest and token
            d["lyapunov"] = True
        return d

    def scene_dict(self) -> dict:
        """The scene as JSON-able data (Parquet metadata ``gyrosim.scene``)."""
        return self.scene.to_dict()

    def token(self) -> str:
        """A short hash of the scene and spec (Dask task keys)."""
        text = json.dumps([self.scene_dict(), self.spec_dict(), self.chunk_size, self.version], sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    @property
    def varied_names(self) -> list[str]:
        return [n for n, _ in self.vary]


def load_sweep_scene(scene) -> tuple[Scene, dict]:
    """The scene and its ``[sweep]`` table (``{}`` when it has none): a TOML file's ``[sweep]`` is taken out before
    the scene is validated; embedded names, ``None`` and :class:`Scene` objects have none."""
    from ..scene import EMBEDDED_SCENES

    if isinstance(scene, (str, Path)) and str(scene) not in EMBEDDED_SCENES + ("full",) \
            and Path(scene).is_file():
        from ..scene import read_scene_file

        path = Path(scene)
        data = read_scene_file(path)
        table = data.pop("sweep", {})
        if not isinstance(table, dict):
            raise ConfigError("sweep", table, "a table [sweep]", where=str(path))
        for k in table:
            if k not in SWEEP_KEYS:
                raise ConfigError(k, table[k], f"a key of [sweep]: one of {', '.join(SWEEP_KEYS)}"
                                  f"{did_you_mean(k, SWEEP_KEYS)}", where=f"{path} [sweep]")
        for k in ("vary", "set"):
            if k in table and not isinstance(table[k], dict):
                raise ConfigError(k, table[k], f"a table [sweep.{k}] of NAME = "
                                  + ('"DIST"' if k == "vary" else "VALUE"), where=f"{path} [sweep]")
        return scene_from_dict(data, str(path)), table
    return load_scene(scene), {}


def _int(value, name: str, lo: int, where: str | None = None) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        try:
            f = float(value)
        except (TypeError, ValueError):
            f = math.nan
        if not (math.isfinite(f) and f == int(f)):
            raise ConfigError(name, value, f"an integer >= {lo}", where=where)
        value = int(f)
    if value < lo:
        raise ConfigError(name, value, f"an integer >= {lo}", where=where)
    return int(value)


def _positive_float(value, name: str, where: str | None = None) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        v = math.nan
    if not (math.isfinite(v) and v > 0):
        raise ConfigError(name, value, "a finite number > 0 in s", where=where)
    return v


def _variables(scene: Scene) -> dict:
    return scene.variables()


def _settable(scene: Scene) -> dict:
    """name -> Variable of the names a sweep may set or vary in ``scene`` (plus ``tolerance``)."""
    from ..model import Variable

    v = {n: var for n, var in _variables(scene).items() if var.causality in ("parameter", "input")
         or n in scene.state_names()}
    v["tolerance"] = Variable("tolerance", "parameter", "fixed", "Real", "1",
                              "relative and absolute tolerance of adaptive and dop853", scene.tolerance,
                              **POSITIVE.fields())
    return v


_TERMS = {"mass": "gravity (a body with cm_distance)", "cm_distance": "gravity (a body with cm_distance)",
          "g": "gravity (a body with cm_distance)", "damping": "damping (a body with damping)",
          "tau_x": "torque inputs (torque_input = true)", "tau_y": "torque inputs (torque_input = true)",
          "tau_z": "torque inputs (torque_input = true)"}


def _check_name(name: str, scene: Scene, settable: dict, flag: str) -> None:
    if name in settable:
        return
    allowed = list(settable)
    if name in _variables(scene):
        raise ConfigError(flag, name, "a parameter, an input or a state start (q_*, omega_*); "
                          f"{name} is a derived output")
    why = f" (it has no {_TERMS[name]}: use a scene file that has the term)" if name in _TERMS else ""
    raise ConfigError(flag, name, f"a variable of scene {scene.name!r}{why}{did_you_mean(name, allowed)}: "
                      + ", ".join(allowed))


def _coerce_fixed(name: str, value, var, flag: str):
    if var.type == "String":
        if value not in INTEGRATORS:
            raise ConfigError(flag, value, f"one of {', '.join(INTEGRATORS)}{did_you_mean(value, INTEGRATORS)}")
        return value
    if isinstance(value, bool):
        raise ConfigError(flag, value, f"a real number in {var.unit or '1'}")
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(flag, value, f"a real number in {var.unit or '1'}") from None
    text, ok = _rule(var)
    if not ok(np.array([x]))[0]:
        raise ConfigError(flag, value, text)
    return x


def _pairs(items, flag: str) -> dict:
    """NAME=VALUE items (a list of strings or a dict) as an ordered dict; a name given twice is an error."""
    if items is None:
        return {}
    if isinstance(items, dict):
        return {str(k).strip(): v for k, v in items.items()}
    out = {}
    for item in items:
        if not isinstance(item, str) or "=" not in item:
            raise ConfigError(flag, item, f"NAME=VALUE, e.g. {flag} " + ("omega_z='uniform(150,250)'"
                                                                          if flag == "--vary" else "I1=2.0"))
        k, v = item.split("=", 1)
        k = k.strip()
        if not k:
            raise ConfigError(flag, item, "NAME=VALUE with a variable name before '='")
        if k in out:
            raise ConfigError(flag, item, f"each name once: {k} is given twice")
        out[k] = v.strip()
    return out


def build_spec(scene=None, *, samples=None, vary=None, set=None, integrator=None, max_step=None,  # noqa: A002
               stop_time=None, output_interval=None, seed=None, chunk_size=None, lyapunov=None) -> SweepSpec:
    """Merge the command line with the scene file's ``[sweep]`` table (the command line wins, name by name) and
    check everything that can be checked before any work: names, distributions, fixed values, and every sample's
    draws (:func:`gyrosim.sweep.sampling.check_draws`).

    Parameters
    ----------
    scene : str, Path, Scene or None
        A one-body scene or a tree (one copy of it per sample): embedded name, TOML path (which may carry
        ``[sweep]``), Scene, or None (the full model).
    vary : list of "NAME=DIST" or dict {name: DIST text}
    set : list of "NAME=VALUE" or dict {name: value}
    lyapunov : bool, optional
        Add each sample's largest Lyapunov exponent (column ``lyapunov``, 1/s); default the ``[sweep]`` table's
        ``lyapunov`` (false).

    Raises
    ------
    ConfigError
        The first problem found, naming the flag or key, the value and what is allowed.
    """
    import gyrosim

    sc, table = load_sweep_scene(scene)
    where = f"{sc.source} [sweep]"
    if sc.n_systems != 1:
        raise ConfigError("scene", sc.name, "one system (a one-body scene or a tree): a sweep replicates it once "
                          f"per sample (this scene has {sc.n_systems} bodies, each its own system)")
    settable = _settable(sc)

    cli_vary, cli_set = _pairs(vary, "--vary"), _pairs(set, "--set")
    for flag, value, name in (("--integrator", integrator, "integrator"), ("--max-step", max_step, "max_step")):
        if value is not None:
            if name in cli_set:
                raise ConfigError(flag, value, f"one value: --set {name}= is given too")
            cli_set[name] = value
    for n in cli_vary:
        if n in cli_set:
            raise ConfigError("--vary", n, f"a name that is not also fixed: --set/--{n.replace('_', '-')} gives "
                              f"{n} a value too")
    file_vary, file_set = _pairs(table.get("vary"), "vary"), _pairs(table.get("set"), "set")
    for k in ("integrator", "max_step"):
        if k in table:
            if k in file_set:
                raise ConfigError(k, table[k], f"one value: [sweep.set] {k} is given too", where=where)
            file_set[k] = table[k]
    for n in file_vary:
        if n in file_set:
            raise ConfigError(n, file_vary[n], "a name in [sweep.vary] or [sweep.set], not both", where=where)
    # the command line wins, name by name
    merged_vary = {n: (d, f"{sc.source} [sweep.vary]") for n, d in file_vary.items() if n not in cli_set}
    merged_vary.update({n: (d, "--vary") for n, d in cli_vary.items()})
    merged_set = {n: (v, f"{sc.source} [sweep.set]") for n, v in file_set.items() if n not in cli_vary}
    merged_set.update({n: (v, "--set") for n, v in cli_set.items()})

    samples = samples if samples is not None else table.get("samples")
    if samples is None:
        raise ConfigError("--samples", None, "a number of samples >= 1 (or samples in the scene's [sweep] table)")
    samples = _int(samples, "--samples", 1)
    if samples > MAX_SAMPLES:
        raise ConfigError("--samples", samples, f"a number of samples from 1 to {MAX_SAMPLES:,} (each a Parquet row; "
                          "split a larger study into sweeps of their own --seed)")
    seed = _int(seed if seed is not None else table.get("seed", 0), "--seed", 0)
    if seed >= 2 ** 63:
        raise ConfigError("--seed", seed, "an integer from 0 to 2**63 - 1")
    cs = chunk_size if chunk_size is not None else table.get("chunk_size")
    cs = min(samples, DEFAULT_CHUNK) if cs is None else _int(cs, "--chunk-size", 1)
    stop = _positive_float(stop_time if stop_time is not None else table.get("stop_time", sc.stop_time),
                           "--stop-time")
    dt = _positive_float(output_interval if output_interval is not None
                         else table.get("output_interval", sc.output_interval), "--output-interval")
    if dt > stop * (1 + 1e-9):
        raise ConfigError("--output-interval", dt, f"at most the stop time {stop!r} s")
    from ..trajectory import output_intervals

    n = output_intervals(stop, dt, stop)

    dists = []
    for name, (text, flag) in merged_vary.items():
        _check_name(name, sc, settable, flag)
        var = settable[name]
        dists.append((name, parse_dist(text, name, string=var.type == "String", unit=var.unit or "1", flag=flag)))
    fixed = []
    for name, (value, flag) in merged_set.items():
        _check_name(name, sc, settable, flag)
        fixed.append((name, _coerce_fixed(name, value, settable[name], f"{flag} {name}")))
    lyap = lyapunov if lyapunov is not None else table.get("lyapunov", False)
    if not isinstance(lyap, bool):
        raise ConfigError("lyapunov", lyap, "true or false", where=where)
    spec = SweepSpec(scene=sc, samples=samples, seed=seed, vary=tuple(dists), fixed=tuple(fixed), stop_time=stop,
                     output_interval=dt, n_intervals=n, chunk_size=cs, version=gyrosim.__version__, lyapunov=lyap)
    check_spec(spec)
    return spec


def base_values(spec: SweepSpec) -> dict:
    """The value of every settable name before the draws: the scene's start values with the fixed ones applied."""
    values = {n: v.start for n, v in _settable(spec.scene).items()}
    values.update(dict(spec.fixed))
    return values


def check_spec(spec: SweepSpec) -> None:
    """The checks that need every sample, before any work: every sample's draws in blocks
    (:func:`gyrosim.sweep.sampling.check_draws`, naming the first bad sample), then a trial model with the fixed
    values and sample 0's draws, initialised and called for zero intervals (the Model's own rules and messages)."""
    from ..model import Model
    from .runner import result_columns
    from .sampling import check_draws, draw

    seen: dict = {}
    for c, _ in result_columns(spec):  # a dataset's column names are unique, or no reader opens it
        if c in seen:
            raise ConfigError("--vary", c, f"a name whose column is not also another column: {c!r} is a column of "
                              "the dataset already (a final output or a summary)")
        seen[c] = True
    check_draws(spec)
    m = Model(spec.scene, stop_time=spec.stop_time)
    first = {n: v[0] for n, v in draw(spec, 0, 1).items()}
    values = {}
    for name, value in list(spec.fixed) + list(first.items()):
        if name == "tolerance":
            try:
                m.set_tolerance(float(value))
            except ConfigError as e:
                raise ConfigError(f"{'--vary' if name in first else '--set'} {name}", e.value, e.allowed) from None
        else:
            values[name] = value.item() if isinstance(value, np.generic) else value
    try:   # each value's range, then the values together (a joint's stops, a start within them), in any order
        m.set_values(values)
    except ConfigError as e:   # named with the flag that gave it, where one did
        flag = "--vary " if e.field in first else "--set " if e.field in dict(spec.fixed) else ""
        raise ConfigError(f"{flag}{e.field}", e.value, e.allowed) from None
    m.initialize()
    m.trajectory(spec.output_interval, 0)  # the call's checks (exact on a torque-free body, bounded work)


def _fmt(v) -> str:
    return repr(v) if isinstance(v, str) else f"{float(v):.12g}"


def check_block(spec: SweepSpec, a: int, draws: dict) -> None:
    """Every rule a sample's values must meet, for samples ``a, a+1, ...`` with ``draws`` (name -> array of the
    varied names); raises for the first bad sample, with the number of bad ones in the block."""
    base = base_values(spec)
    if not draws:
        return
    n = len(next(iter(draws.values())))
    settable = _settable(spec.scene)
    fixed = dict(spec.fixed)

    def fail(mask, show, allowed, advice="narrow the distribution"):
        bad = np.flatnonzero(mask)
        i = int(bad[0])
        vals = ", ".join(f"{k} = {_fmt(draws[k][i] if k in draws else base[k])}" for k in show)
        name = next((k for k in show if k in draws), None)
        label = f"--vary {name}" if name else next((f"--set {k}" for k in show if k in fixed), "scene")
        raise ConfigError(
            label, f"sample {a + i}: {vals}",
            f"{allowed} ({len(bad):,} of samples {a:,}..{a + n - 1:,} break this rule; every sample's draws are "
            f"checked before any work starts: {advice})")

    for name, values in draws.items():
        var = settable[name]
        if var.type == "String":
            continue
        text, ok = _rule(var)
        mask = ~ok(np.asarray(values, dtype=float))
        if mask.any():
            fail(mask, [name], text, "narrow the distribution" + (", e.g. lognormal(mean,sigma) for a quantity > 0"
                                                                  if "> 0" in text else ""))

    def arr(k):
        return np.asarray(draws[k], dtype=float) if k in draws else np.full(n, float(base[k]))

    if any(k in draws for k in ("I1", "I2", "I3")):  # a lone body's principal moments
        from ..core.inertia import TRIANGLE_RTOL

        I = np.stack([arr("I1"), arr("I2"), arr("I3")], axis=1)
        mask = ~np.all(I[:, [1, 2, 0]] + I[:, [2, 0, 1]] >= I * (1.0 - TRIANGLE_RTOL), axis=1)
        if mask.any():
            try:
                check_principal_moments(*I[int(np.flatnonzero(mask)[0])])
                rule = "the triangle inequality"
            except ConfigError as e:
                rule = f"{e.field} {e.allowed}"
            fail(mask, ["I1", "I2", "I3"], f"principal moments that a body can have: {rule}",
                 "narrow the moments' distributions so that every draw is a body")
    qs = ("q_w", "q_x", "q_y", "q_z")
    if any(k in draws for k in qs):
        q = np.stack([arr(k) for k in qs], axis=1)
        mask = ~(np.abs(np.sqrt((q * q).sum(axis=1)) - 1.0) <= 1e-6)
        if mask.any():
            fail(mask, list(qs), "a unit quaternion, |q| = 1 within 1e-6",
                 "vary the rates, or give the attitude in a scene file")
    if "max_step" in draws:
        ms = arr("max_step")
        mask = spec.output_interval / ms > _engine.MAX_WORK * 0.999
        for i in np.flatnonzero(mask):  # the engine's own count decides near the bound
            mask[i] = _engine.substeps(spec.output_interval, float(ms[i])) == 0
        if mask.any():
            fail(mask, ["max_step"], f"at least output_interval / {_engine.MAX_WORK:,} (an output interval may take "
                 f"at most {_engine.MAX_WORK:,} internal steps; output_interval = {spec.output_interval!r} s)",
                 "raise the smallest max_step")
    integ = np.asarray(draws["integrator"]) if "integrator" in draws else np.full(n, base["integrator"])
    is_exact = integ == "exact"
    if is_exact.any():
        sc = spec.scene
        terms = []
        if sc.gravity:
            terms.append(("mass*g*cm_distance", arr("mass") * arr("g") * arr("cm_distance"),
                          ["mass", "g", "cm_distance"]))
        if sc.damping:
            terms.append(("damping", arr("damping"), ["damping"]))
        if sc.torque:
            terms += [(k, arr(k), [k]) for k in ("tau_x", "tau_y", "tau_z")]
        for what, value, show in terms:
            mask = is_exact & (value != 0.0)
            if mask.any():
                fail(mask, ["integrator", *show], f"a torque-free body where the integrator is 'exact' ({what} = 0; "
                     "'exact' solves the torque-free flow)", "choose another integrator for these samples")
