"""A scene's engine system as the FMU glue sees it: the rows of ``core/engine/gyrosim_system.h`` and the variable table.

Every FMU compiles one glue (``c/gyrosim_model.c``) that knows no scene: :func:`system_layout` says what the scene's
system is (its description for ``gs_sys_init``, its row sizes, start rows, where each parameter, input and
coordinate lives, its quaternions, the continuous states of model exchange and their nominal values), and
:func:`fmu_rows` maps every variable of :meth:`Scene.variables <gyrosim.scene.Scene.variables>` (value references from
1, in that order) to what it is to the glue: a slot of the parameter row (``param``: effective at initialisation;
``max_drift``, ``input``: at once), a scene parameter (``alias``, with its targets and factors), a coordinate of the
state (``state``: an output with a settable start value), a column of the output row (``output``), ``integrator``,
``max_step``; :func:`me_rows` adds model exchange's locals after them (a work integral's balance as a state,
``work``, and the derivative ``der(<state>)`` of every continuous state).

The kernel is asked once, in :func:`system_layout` (as ``gs_sys_init`` dispatches on the description's tag); the rest
reads the layout.

FMI 3.0 adds :func:`fmu_arrays` (array variables, views of the scalars: ``q_world`` [4], ``omega`` [3], ``L`` [3],
``inertia`` [3, 3], ``joint_angles``) and :func:`fmu_terminals` (terminalsAndIcons.xml: a frame per body, a flange per
hinge or slider).
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from importlib import resources

import numpy as np

from ..core import _engine
from ..core.tree import BODY_OUTPUTS, BODY_SLOTS, INPUT_SLOTS, ORBIT_COORD
from ..errors import ConfigError
from ..kernel_body import STATE_NAMES
from ..scene import Scene
from ..scene_tree import NONNEGATIVE_PARAMS

__all__ = ["SystemLayout", "FmuRow", "system_layout", "fmu_variables", "fmu_rows", "SCENE_SETTINGS",
           "me_rows", "jacobian_pattern", "range_rows", "SYSTEM", "WORK_STATE", "DER_UNITS", "STATES",
           "FmuArray", "fmu_arrays", "ARRAY_STEMS", "JOINT_ANGLES", "FmuTerminal", "fmu_terminals", "FRAME_KIND",
           "FLANGE_KINDS"]

#: gyrosim_system.h's constants (GS_KERNEL_*, GS_SP_*, GS_SB_*), read from the header the glue compiles.
SYSTEM = {m[1]: int(m[2]) for m in re.finditer(
    r"#define GS_((?:KERNEL|SP|SB)_\w+) (\d+)",
    resources.files("gyrosim.core").joinpath("engine", "gyrosim_system.h").read_text())}
#: Model exchange: the name of a work integral's balance as a continuous state (the tree's y[nx]).
WORK_STATE = "energy_expected"
#: The unit of a state's derivative by the state's unit.
DER_UNITS = {"1": "1/s", "rad": "rad/s", "rad/s": "rad/s2", "m": "m/s", "m/s": "m/s2", "J": "W"}
#: The coordinates of a body of the one-body kernel, in the order of its state row.
STATES = STATE_NAMES


@dataclass
class SystemLayout:
    """The engine system of a scene (gyrosim_system.h).

    ``head``: scene-wide parameter slots by variable name; ``body_slots`` / ``input_slots``: a body parameter's or
    input's slot in the body's block (from ``body_offset[b]``); ``coords``: the y slot of every coordinate by
    ``(body, short name)``, ``coord_index``: its coordinate (model exchange's state index) by y slot; ``quats``:
    ``(y slot of q_w, name)``; ``work_states``: the work integrals are continuous states (``energy_expected``) rather
    than accumulated by the glue; ``nonneg``: variable short names that must be >= 0 beyond their range."""

    desc: list[int]
    ny: int
    np: int
    nout: int
    ncoord: int
    nwork: int
    nex: int
    units: int
    unit_names: list[str]
    p0: np.ndarray
    y0: np.ndarray
    head: dict[str, int]
    body_offset: list[int]
    body_slots: dict[str, int]
    input_slots: dict[str, int]
    coords: dict[tuple, int]
    coord_index: dict[int, int]
    quats: list[tuple[int, str]]
    work_states: bool
    nominals: list[float]
    states_text: str
    nonneg: frozenset = frozenset()
    energy_error: list[int] = field(default_factory=list)   # the energy_error column of each work integral
    head_inputs: dict[str, int] = field(default_factory=dict)   # inputs outside a body's block (force elements)
    indicators: list[str] = field(default_factory=list)   # model exchange's event indicators (impact stops)
    pattern: object = None   # (rows) -> (ddy, dout) where the derivatives can be nonzero

    @property
    def nx(self) -> int:
        """Model exchange's continuous states."""
        return self.ncoord + (self.nwork if self.work_states else 0)

    @property
    def ndy(self) -> int:
        return self.ncoord + self.nwork


@dataclass(frozen=True)
class FmuRow:
    """One FMU variable: its name, :class:`~gyrosim.model.Variable` (None for model exchange's locals), what it is to
    the glue (``kind``), the index that kind takes (a parameter-row slot, an alias row, a y slot, an output column, a
    continuous-state index), ``aux`` (a state's coordinate; a work state's energy_error column) and whether it must
    be >= 0."""

    name: str
    var: object
    kind: str
    index: int = 0
    aux: int = 0
    nonneg: bool = False


def _body_layout(sc: Scene) -> SystemLayout:
    """Independent bodies on the one-body kernel (Euler's equations, exact flows, splittings)."""
    n, head, nb = len(sc.bodies), SYSTEM["SP_HEAD"], SYSTEM["SB_NP"]
    ny = _engine.NY
    g = sc.g if sc.gravity else 0.0   # Model: g of a scene without gravity is 0 (no potential energy term)
    p0 = np.zeros(head + nb * n)
    p0[SYSTEM["SP_DRIFT"]] = sc.max_drift
    y0 = np.zeros(ny * n)
    coords, coord_index, quats, nominals = {}, {}, [], []
    for b, body in enumerate(sc.bodies):
        o = head + nb * b
        p0[o + SYSTEM["SB_I"]:o + SYSTEM["SB_I"] + 3] = body.moments
        p0[o + SYSTEM["SB_MASS"]], p0[o + SYSTEM["SB_CM"]] = body.mass, body.cm_distance
        p0[o + SYSTEM["SB_G"]], p0[o + SYSTEM["SB_DAMPING"]] = g, body.damping
        y0[ny * b:ny * b + 4], y0[ny * b + 4:ny * b + 7] = body.q0, body.omega0
        rate = max(1.0, *(abs(float(w)) for w in body.omega0))   # the body's largest start rate, at least 1
        for k, st in enumerate(STATES):
            coords[(b, st)] = ny * b + k
            coord_index[ny * b + k] = len(STATES) * b + k
            nominals.append(1.0 if k < 4 else rate)
        quats.append((ny * b, sc.var_name(body.name, "q")))
    sb = {"I1": SYSTEM["SB_I"], "I2": SYSTEM["SB_I"] + 1, "I3": SYSTEM["SB_I"] + 2, "mass": SYSTEM["SB_MASS"],
          "cm_distance": SYSTEM["SB_CM"], "g": SYSTEM["SB_G"], "damping": SYSTEM["SB_DAMPING"]}
    tau = SYSTEM["SB_TAU"]
    gravity = bool(sc.flags & _engine.GRAVITY)

    def pattern(rows):   # Euler's equations: which derivatives can be nonzero (per body; the bodies independent)
        inputs = [r for r in rows if r.kind == "input"]
        nk = len(STATES) * n + len(inputs)
        ddy, dout = np.zeros((len(STATES) * n + n, nk), bool), np.zeros((_engine.NOUT * n, nk), bool)
        for b in range(n):
            q, w = [len(STATES) * b + k for k in range(4)], [len(STATES) * b + k for k in range(4, 7)]
            taus = [len(STATES) * n + j for j, r in enumerate(inputs)
                    if head + nb * b <= r.index < head + nb * (b + 1)]
            for k in range(4):
                ddy[len(STATES) * b + k, q + w] = True
            for k in range(4, 7):
                ddy[len(STATES) * b + k, (q if gravity else []) + w + taus] = True
            o = _engine.NOUT * b
            for k in range(7):
                dout[o + k, len(STATES) * b + k] = True
            dout[o + 7:o + 10, q[0]] = True   # phi, theta, psi: q (the closure adds all four)
            for c in [q[0], *w]:   # L, energy, energy_error: q and omega
                dout[o + 10:o + 15, c] = True
        return ddy, dout

    return SystemLayout(
        desc=[SYSTEM["KERNEL_BODY"], sc.flags, n], ny=ny * n, np=head + nb * n, nout=_engine.NOUT * n,
        ncoord=len(STATES) * n, nwork=n, nex=_engine.EX_SIZE, units=n, unit_names=sc.body_names, p0=p0, y0=y0,
        head={"max_drift": SYSTEM["SP_DRIFT"]}, body_offset=[head + nb * b for b in range(n)], body_slots=sb,
        input_slots={"tau_x": tau, "tau_y": tau + 1, "tau_z": tau + 2}, coords=coords, coord_index=coord_index,
        quats=quats, work_states=False, nominals=nominals,
        states_text="q_w, q_x, q_y, q_z, omega_x, omega_y, omega_z of every body", pattern=pattern)


#: A tree body's parameter slots in its block (core/engine/gyrosim_tree.h GS_TB_*) and its inputs'.
_TREE_BODY_SLOTS = BODY_SLOTS
_TREE_INPUT_SLOTS = INPUT_SLOTS


def _tree_layout(sc: Scene) -> SystemLayout:
    """A tree of bodies on the articulated-body algorithm."""
    from ..kernel_tree import contacts_of, element_columns, tree_layout
    from ..model import Model

    lay = tree_layout(sc)
    p0, y0 = lay.params(float(sc.g), float(sc.max_drift)), lay.state()
    head = {"g": _engine.TP_G, "max_drift": _engine.TP_DRIFT, "orbit_mu": _engine.TP_MU,
            "orbit_radius": _engine.TP_ORBIT_R}
    head.update({name: lay.body_offset(len(sc.tree)) + i for i, name in enumerate(sc.coupling_names)})
    elements = sc.element_variables()
    head_inputs = {}
    for name, col in element_columns(sc, lay).items():
        (head_inputs if elements[name][0] == "force" else head)[name] = col
    quats = [(lay.coord_slots[(i, "q_w")], sc.var_name(b.name, "q")) for i, b in enumerate(sc.tree)
             if (i, "q_w") in lay.coord_slots]
    by_slot = {k: short for (_, short), k in lay.coord_slots.items()}
    nominals = []
    for k in range(lay.nx):   # 1 for quaternions, angles, positions; the start rate (at least 1) for rates
        fast = by_slot.get(k, "").startswith(("omega_", "v_")) or by_slot.get(k) in ("rate", "velocity")
        nominals.append(max(1.0, abs(float(y0[k]))) if fast else 1.0)
    nominals.append(max(1.0, abs(float(Model(sc).get("energy")))))
    joints = {b.joint for b in sc.tree}
    coords = [what for what, on in (("quaternions and angular velocities", joints & {"ball", "free_rotation", "free"}),
                                    ("hinge angles and rates", "hinge" in joints),
                                    ("slider displacements and velocities", "slider" in joints),
                                    ("positions and velocities", "free" in joints)) if on]
    anomaly = any(short == ORBIT_COORD for _, short in lay.coord_slots)   # a circular orbit's

    def pattern(rows):   # the complex step at two generic points: an entry zero at both is zero by the equations
        return tuple(a | b for a, b in zip(*(_tree_pattern(sc, lay, rows, seed) for seed in (1, 2))))

    return SystemLayout(
        desc=[SYSTEM["KERNEL_TREE"], *(int(x) for x in lay.desc)], ny=lay.ny, np=lay.np, nout=lay.nout,
        ncoord=lay.nx, nwork=1, nex=0, units=1, unit_names=[sc.name], p0=p0, y0=y0, head=head,
        body_offset=[lay.body_offset(b) for b in range(len(sc.tree))], body_slots=_TREE_BODY_SLOTS,
        input_slots=_TREE_INPUT_SLOTS, coords=dict(lay.coord_slots), coord_index={k: k for k in range(lay.nx)},
        quats=quats, work_states=True, nominals=nominals,
        states_text=f"the joints' coordinates ({', '.join(coords)}){', the orbit anomaly' if anomaly else ''} and "
                    f"{WORK_STATE}",
        nonneg=frozenset({"g", "orbit_mu", "orbit_radius", *NONNEGATIVE_PARAMS, *sc.coupling_names,
                          *(n for n, (kind, _, _) in elements.items() if kind == "spring")}),
        head_inputs=head_inputs,
        indicators=[(sc.var_name(b.name, f"{side}_stop_distance"), "m" if b.joint == "slider" else "rad")
                    for b in sc.tree if b.stop == "impact"
                    for side, lim in (("lower", b.lower), ("upper", b.upper)) if lim is not None] + [
            (sc.var_name(sc.tree[h.body].name, f"{stem}.{what}"), "1") for h, pl, stem in contacts_of(sc)
            if pl.model == "rigid" for what in ("contact_event", "friction_event")],
        energy_error=[lay.nx + len(BODY_OUTPUTS) * len(sc.tree) + 1], pattern=pattern)


def _tree_pattern(sc: Scene, lay, rows, seed: int):
    from ..kernel_tree import alias_targets, tree_layout

    """``(ddy (nx + 1, nx + n_inputs), dout (nout, nx + n_inputs))``: where the tree engine's derivatives are not zero
    at a random state, parameters and inputs; columns the coordinates, then the inputs of ``rows`` in their order."""
    rng = np.random.default_rng(seed)
    p = lay.params(float(sc.g), float(sc.max_drift)).copy()
    slots = [r.index for r in rows if r.kind in ("param", "input")]
    slots += [col for a in sc.aliases for col, _, _, _ in alias_targets(sc, tree_layout(sc), a)]
    for k in slots:
        if k != _engine.TP_DRIFT:
            p[k] = rng.uniform(0.5, 1.5)
    y = lay.state().copy()
    y[:lay.nx] = rng.normal(size=lay.nx)
    for b in range(len(sc.tree)):
        if (b, "q_w") in lay.coord_slots:
            k = lay.coord_slots[(b, "q_w")]
            y[k:k + 4] /= np.linalg.norm(y[k:k + 4])
    inputs = [r.index for r in rows if r.kind == "input"]
    n = lay.nx + len(inputs)
    ddy, dout = np.zeros((n, lay.nx + 1)), np.zeros((n, lay.nout))   # a column per row here: transposed below
    for j in range(n):
        vy, vp = np.zeros(lay.nx), np.zeros(lay.np)
        if j < lay.nx:
            vy[j] = 1.0
        else:
            vp[inputs[j - lay.nx]] = 1.0
        _engine.tree_directional(lay.desc, y.reshape(1, -1), p.reshape(1, -1), vy, vp, ddy[j], dout[j])
    if sc.shapes or getattr(sc, "loops", ()) or getattr(sc, "gears", ()):
        # a contact's forces couple what its state couples, and a random state may hold it apart (a rigid contact's
        # mode is apart in the start row); a closed loop's or a gear's constraint solve couples every joint of the
        # tree through the mass matrix: every derivative and output may depend on every coordinate and input
        return np.ones_like(ddy.T, dtype=bool), np.ones_like(dout.T, dtype=bool)
    return ddy.T != 0.0, dout.T != 0.0


_LAYOUTS = {"body": _body_layout, "tree": _tree_layout}


def system_layout(sc: Scene) -> SystemLayout:
    """The engine system of scene ``sc``: the kernel picked for it at set-up (:attr:`Scene.kernel`), asked once."""
    return _LAYOUTS[sc.kernel](sc)


def _split(sc: Scene, name: str) -> tuple[int | None, str]:
    """The body (its index) and short name of variable ``name`` (:meth:`Scene.split_name`); a bare body parameter of a
    scene of one body (``g`` of a pivoted body) is that body's."""
    bi, short = sc.split_name(name)
    if bi is None and "." not in name and len(sc.body_names) == 1:
        return 0, short
    return bi, short


#: Settings of the whole scene: a scene of several independent bodies lists them under every body's name
#: (:meth:`Scene.variables`); the FMU has each once, first, under its bare name.
SCENE_SETTINGS = ("integrator", "max_step", "max_drift")


def fmu_variables(sc: Scene) -> list[tuple[str, object]]:
    """``(name, Variable)`` of the FMU's variables in value-reference order (from 1): :meth:`Scene.variables`, the
    scene's settings (:data:`SCENE_SETTINGS`) once where they are listed per body."""
    items = list(sc.variables().items())
    if not any("." in n and n.rpartition(".")[2] in SCENE_SETTINGS for n, _ in items):
        return items
    first = {}
    for n, v in items:
        first.setdefault(n.rpartition(".")[2], v)
    return [(s, first[s]) for s in SCENE_SETTINGS if s in first] + \
        [(n, v) for n, v in items if n.rpartition(".")[2] not in SCENE_SETTINGS]


def fmu_rows(sc: Scene, lay: SystemLayout | None = None) -> list[FmuRow]:
    """The variables of ``sc`` in value-reference order (from 1), each mapped to the glue's kind.

    Raises
    ------
    ConfigError
        A variable the glue cannot map, or a start value that is not the system's start row's (the table would be
        wrong).
    """
    lay = lay or system_layout(sc)
    aliases = {a.name: i for i, a in enumerate(sc.aliases)}
    columns = {name: i for i, name in enumerate(sc.output_names())}
    rows = []
    for name, v in fmu_variables(sc):
        bi, short = _split(sc, name)
        nonneg = short in lay.nonneg
        if name in ("integrator", "max_step"):
            row = FmuRow(name, v, name)
        elif short == "max_drift":
            row = FmuRow(name, v, "max_drift", lay.head["max_drift"])
        elif name in lay.head:
            row = FmuRow(name, v, "param", lay.head[name], nonneg=nonneg or name in lay.nonneg)
        elif name in lay.head_inputs:
            row = FmuRow(name, v, "input", lay.head_inputs[name])
        elif name in aliases:
            row = FmuRow(name, v, "alias", aliases[name])
        elif v.causality == "parameter" and bi is not None and short in lay.body_slots:
            row = FmuRow(name, v, "param", lay.body_offset[bi] + lay.body_slots[short], nonneg=nonneg)
        elif v.causality == "input" and bi is not None and short in lay.input_slots:
            row = FmuRow(name, v, "input", lay.body_offset[bi] + lay.input_slots[short])
        elif v.causality == "output" and v.start is not None and (bi, short) in lay.coords or \
                (None, name) in lay.coords:
            k = lay.coords.get((bi, short), lay.coords.get((None, name)))
            row = FmuRow(name, v, "state", k, lay.coord_index[k])
        elif v.causality == "output" and name in columns:
            row = FmuRow(name, v, "output", columns[name])
        else:
            raise ConfigError("variable", name, "a variable the FMU's table knows (a parameter, an input, a "
                              "coordinate or an output of the engine's row)")
        start = {"param": lay.p0, "max_drift": lay.p0, "state": lay.y0}.get(row.kind)
        if start is not None and float(start[row.index]) != float(v.start):
            raise ConfigError("variable", name, f"a start value equal to the system's row ({v.start!r} in the "
                              f"variables, {float(start[row.index])!r} in slot {row.index})")
        rows.append(row)
    return rows


def me_rows(lay: SystemLayout, rows: list[FmuRow]) -> list[FmuRow]:
    """Model exchange's local variables after ``rows``: the work integrals' balances where they are states
    (``energy_expected``), the derivatives ``der(...)`` of the continuous states in their order, then the event
    indicators (``<body>.lower_stop_distance``, ``upper_...``: an impact stop's distance, >= 0 within the stops)."""
    states = {r.aux: r.name for r in rows if r.kind == "state"}
    out = []
    if lay.work_states:
        for u in range(lay.nwork):
            states[lay.ncoord + u] = WORK_STATE
            out.append(FmuRow(WORK_STATE, None, "work", lay.ncoord + u, lay.energy_error[u]))
    from ..variables import Variable

    return out + [FmuRow(f"der({states[i]})", None, "der", i) for i in range(lay.nx)] + \
        [FmuRow(name, Variable(name, "local", "continuous", "Real", unit, _indicator_text(name), None), "indicator", k)
         for k, (name, unit) in enumerate(lay.indicators)]


def _indicator_text(name: str) -> str:
    """An event indicator's description: an impact stop's distance, or a rigid contact's two (constraints.h)."""
    if name.endswith(".contact_event"):
        return ("event indicator of a rigid contact: its gap while apart (m; touch-down where it reaches 0), its "
                "normal force while touching (N; lift-off where it reaches 0)")
    if name.endswith(".friction_event"):
        return ("event indicator of a rigid contact's friction: the slip along its direction while sliding (m/s; "
                "it sticks where it reaches 0), the friction cone's margin while sticking (N; it slides where it "
                "reaches 0), 1 otherwise")
    return (f"event indicator: the distance to the {name.rsplit('.', 1)[-1].split('_')[0]} impact stop (>= 0 within "
            "the stops; an impact where it reaches 0)")


def jacobian_pattern(lay: SystemLayout, rows: list[FmuRow]):
    """Where the system's derivatives can be nonzero: ``(ddy (ndy, ncoord + n_inputs), dout (nout, ncoord +
    n_inputs))`` as booleans, columns the coordinates, then the inputs of ``rows`` in their order."""
    return lay.pattern(rows)


def range_rows(rows: list[FmuRow]) -> list[tuple[int, object]]:
    """The rows whose values the glue checks against a range at every set: ``(position, Variable)``."""
    return [(i, r.var) for i, r in enumerate(rows)
            if r.kind in ("param", "alias", "max_drift", "max_step", "input", "state") and r.var is not None
            and r.var.type == "Real"
            and r.var.range.bounded and (math.isfinite(r.var.range.min) or math.isfinite(r.var.range.max))]


# ------------------------------------------------------------------------------------------ FMI 3.0 arrays, terminals

#: The array variables made of scalar stems (FMI 3.0): ``<stem>`` is the array of ``<stem>_<component>`` in this order
#: wherever the scene has all of them (``q``, ``q_world``, ``<body>.q_world``, ``omega``, ``L``, ...).
ARRAY_STEMS = {"q": ("w", "x", "y", "z"), "q_world": ("w", "x", "y", "z"), "omega": ("x", "y", "z"),
               "L": ("x", "y", "z")}
#: The array of a tree's hinge angles.
JOINT_ANGLES = "joint_angles"


@dataclass(frozen=True)
class FmuArray:
    """An FMI 3.0 array variable: another view of scalar variables (getting it reads them, setting it sets them).

    ``elements``: the value reference of each element's scalar variable, row-major; 0 for an element that is no
    variable (an inertia's product of inertia), whose value is the parameter-row slot ``fixed[k]`` (-1: 0), fixed.
    ``labels``: each element as messages name it (``omega[1] (omega_x)``, 1-based as FMI's element indices)."""

    name: str
    shape: tuple
    elements: tuple
    fixed: tuple
    labels: tuple
    what: str


def _index_label(shape, k: int) -> str:
    idx = np.unravel_index(k, shape)
    return ",".join(str(int(i) + 1) for i in idx)


def _array(name, shape, elements, names, what, fixed=None) -> FmuArray:
    fixed = tuple(fixed) if fixed is not None else (-1,) * len(elements)
    labels = tuple(f"{name}[{_index_label(shape, k)}]" + (f" ({names[k]})" if names[k] else "")
                   for k in range(len(elements)))
    return FmuArray(name, tuple(shape), tuple(elements), fixed, labels, what)


def fmu_arrays(sc: Scene, lay: SystemLayout, rows: list[FmuRow]) -> list[FmuArray]:
    """The FMI 3.0 array variables of ``sc`` over its scalar variables ``rows`` (value references from 1): every
    complete group of :data:`ARRAY_STEMS` in the order of its scalars, each body's ``inertia`` [3, 3] (the diagonal
    its parameters I1, I2, I3; the products of inertia the system's, fixed), and a tree's :data:`JOINT_ANGLES` (its
    hinges' angles in body order). An array whose name is already a variable's is left out."""
    vr = {r.name: i for i, r in enumerate(rows, start=1)}
    kind = {r.name: r.kind for r in rows}
    out = []
    for r in rows:
        head, dot, short = r.name.rpartition(".")
        stem, _, comp = short.rpartition("_")
        comps = ARRAY_STEMS.get(stem)
        if not comps or comp != comps[0]:
            continue
        name = f"{head}{dot}{stem}"
        names = [f"{name}_{c}" for c in comps]
        if all(n in vr for n in names) and name not in vr:
            settable = "setting it sets them" if kind[names[0]] == "state" else "an output"
            out.append(_array(name, (len(names),), [vr[n] for n in names], names,
                              f"{', '.join(names)} as one array [{len(names)}] (the same values: getting it reads "
                              f"them; {settable})"))
    tree = lay.desc[0] == SYSTEM["KERNEL_TREE"]
    for b, body in enumerate(sc.body_names):
        name = sc.var_name(body, "inertia")
        diag = [sc.var_name(body, f"I{k}") for k in (1, 2, 3)]
        if name in vr or not all(kind.get(n) == "param" for n in diag):
            continue
        o = lay.body_offset[b] + _engine.TB_I if tree else -1
        products = {(0, 1): 3, (0, 2): 4, (1, 2): 5}   # GS_TB_I + 3..5: Ixy, Ixz, Iyz
        elements, fixed, names = [], [], []
        for i in range(3):
            for j in range(3):
                elements.append(vr[diag[i]] if i == j else 0)
                names.append(diag[i] if i == j else "")
                fixed.append(-1 if i == j or not tree else o + products[(min(i, j), max(i, j))])
        out.append(_array(name, (3, 3), elements, names,
                          f"inertia tensor about the centre of mass in the body frame, [3, 3] row-major: the diagonal "
                          f"is {', '.join(diag)} (setting it sets them), the products of inertia are "
                          + ("the scene's, fixed" if tree else "0 (principal body axes)"), fixed))
    if sc.tree is not None and JOINT_ANGLES not in vr:
        names = [sc.var_name(b.name, "angle") for b in sc.tree if b.joint == "hinge"]
        names = [n for n in names if kind.get(n) == "state"]
        if names:
            out.append(_array(JOINT_ANGLES, (len(names),), [vr[n] for n in names], names,
                              f"the hinge angles {', '.join(names)} as one array [{len(names)}] (the same values: "
                              "getting it reads them; setting it sets them)"))
    return out


@dataclass(frozen=True)
class FmuTerminal:
    """A terminal of terminalsAndIcons.xml: ``name``, ``kind`` (terminalKind), ``rule`` (matchingRule), ``members``
    ``[(memberName, variable name)]`` (variableKind ``signal``) and a description."""

    name: str
    kind: str
    rule: str
    members: tuple
    what: str


#: terminalKind of a body's frame and of a hinge's / a slider's flange (vendor kinds: ``_gyrosim_...``).
FRAME_KIND = "_gyrosim_frame"
FLANGE_KINDS = {"hinge": "_gyrosim_rotational_flange", "slider": "_gyrosim_translational_flange"}
_FLANGE_MEMBERS = {"hinge": ("angle", "rate", "motor_torque"), "slider": ("displacement", "velocity", "motor_force")}


def fmu_terminals(sc: Scene, rows: list[FmuRow]) -> list[FmuTerminal]:
    """The terminals of ``sc``: a ``frame`` per body, named after the body (members ``r_world_*``, ``q_world_*``,
    ``v_world_*`` and, where they are the body's rate in the world, ``omega_*``: a root's ball, free_rotation or
    free joint, every body of the one-body kernel, whose ``q`` is then its ``q_world``), and a ``flange`` per hinge
    or slider, named ``<body>.<joint>`` (angle or displacement, rate or velocity, and the motor input where the joint
    has one). Matching rule ``bus``: by member name, members present where the body has them."""
    names = {r.name for r in rows}
    out = []
    joints = {b.name: b for b in sc.tree} if sc.tree is not None else {}
    for body in sc.body_names:
        b = joints.get(body)
        # the attitude: q_world, or the one-body kernel's q (body to world)
        world = "q_world" if b is not None or sc.var_name(body, "q_world_w") in names else "q"
        wanted = [*((f"r_world_{c}", f"r_world_{c}") for c in "xyz"),
                  *((f"q_world_{c}", f"{world}_{c}") for c in "wxyz"),
                  *((f"v_world_{c}", f"v_world_{c}") for c in "xyz")]
        if b is None or (b.parent < 0 and b.joint in ("ball", "free_rotation", "free")):
            wanted += [(f"omega_{c}", f"omega_{c}") for c in "xyz"]
        members = [(m, sc.var_name(body, short)) for m, short in wanted if sc.var_name(body, short) in names]
        if members:
            out.append(FmuTerminal(body, FRAME_KIND, "bus", tuple(members),
                                   f"frame of body {body!r}: its origin's position and velocity in the world, its "
                                   "attitude (body to world) and, where present, its angular velocity in the world "
                                   "in body axes"))
        if b is not None and b.joint in _FLANGE_MEMBERS:
            members = [(m, sc.var_name(body, m)) for m in _FLANGE_MEMBERS[b.joint] if sc.var_name(body, m) in names]
            what = "rotational: angle rad, rate rad/s" if b.joint == "hinge" else \
                "translational: displacement m, velocity m/s"
            motor = " and its motor input" if len(members) > 2 else ""
            out.append(FmuTerminal(f"{body}.{b.joint}", FLANGE_KINDS[b.joint], "bus", tuple(members),
                                   f"flange of the {b.joint} joint of body {body!r} ({what}){motor}"))
    return out
