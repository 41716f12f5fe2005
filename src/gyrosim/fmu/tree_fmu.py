"""FMUs of tree scenes (bodies joined by joints, docs/trees.md): the variable table and model description.

A tree FMU's binary is the engine's tree (``core/engine/tree.c``, ``rk.c``) and one generic glue,
``c/gyrosim_tree_model.c``, which knows no scene: this module writes what is particular to the scene into the
generated ``gyrosim_config.h`` as data,

- the tree's description (``gs_tree_init``'s int32 array), the start parameter row and state (hexadecimal
  floating literals: the bits of :class:`~gyrosim.kernel_tree.TreeModel`'s),
- a table from value reference to ``{kind, index, flags, name, unit, range}``: a slot of the parameter row
  (``GS_K_PARAM``: g, body parameters, couplings; ``GS_K_INPUT``; ``GS_K_MAX_DRIFT``), a scene parameter
  (``GS_K_ALIAS``, with its targets and factors in ``GS_ALIAS_TARGETS``), a joint coordinate of the state
  (``GS_K_STATE``), a column of the engine's output row (``GS_K_OUTPUT``), ``integrator``, ``max_step``, and for
  model exchange the work integral (``GS_K_WORK``) and the state derivatives (``GS_K_DER``); ``range`` a row of
  ``GS_RANGES``, the range of a parameter (:attr:`gyrosim.model.Variable.range`; a scene parameter's from its scene
  file), which the glue checks at every set, as the model description's ``min``/``max`` state it,
- the integrator, max_step and tolerance start values, the quaternions' slots, the states' nominal values.

The variables are exactly :func:`~gyrosim.kernel_tree.tree_variables` (names, causality, variability, units, start
values, in that order from value reference 1). Model exchange adds local variables after them: the continuous
state ``energy_expected`` (J: the energy the work-energy balance expects, E(0) plus the work of the inputs minus
the joints' dissipation; ``energy_error = energy - energy_expected``) and the derivative ``der(<state>)`` of every
continuous state (the joints' coordinates, then ``energy_expected``).
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass

from ..core import _engine
from ..core.tree import TreeLayout
from ..errors import ConfigError
from ..scene import TREE_INTEGRATORS, Scene
from . import build as _build
from .build import ME_NORM_TOL, _hexf, _platforms_note, description_head, model_structure, range_attributes

__all__ = ["TreeRow", "tree_rows", "tree_me_rows", "tree_config_header", "tree_model_description", "tree_dependencies",
           "TREE_ENGINE", "TREE_GLUE", "WORK_STATE", "DER_UNITS"]

#: The engine's files a tree FMU is compiled from (core/engine/) and its glue (fmu/c/).
TREE_ENGINE = ("gyrosim_engine.h", "gyrosim_ode.h", "gyrosim_tree.h", "rk_tables.h", "rk_driver.h", "exact_fast.h",
               "body_dynamics.h", "angles.h", "monitor.h", "splitting.h", "outputs.h", "exact_steps.h", "block.h",
               "engine.c", "exact.c", "rk.c", "tree.c", "tree_cs.c", "cflags.txt")
TREE_GLUE = ("gyrosim_glue_api.h", "gyrosim_glue_common.h", "gyrosim_model.h", "gyrosim_tree_model.h",
             "gyrosim_tree_model.c")
#: Model exchange: the continuous state of the work integral (the engine's y[nx]).
WORK_STATE = "energy_expected"
#: The unit of a state's derivative by the state's unit.
DER_UNITS = {"1": "1/s", "rad": "rad/s", "rad/s": "rad/s2", "m": "m/s", "m/s": "m/s2", "J": "W"}

_KIND_C = {"none": "GS_K_NONE", "time": "GS_K_TIME", "param": "GS_K_PARAM", "max_drift": "GS_K_MAX_DRIFT",
           "input": "GS_K_INPUT", "alias": "GS_K_ALIAS", "state": "GS_K_STATE", "output": "GS_K_OUTPUT",
           "integrator": "GS_K_INTEGRATOR", "max_step": "GS_K_MAX_STEP", "work": "GS_K_WORK", "der": "GS_K_DER"}
#: g and max_drift in the parameter row (gyrosim_tree.h GS_TP_G, GS_TP_DRIFT; TreeLayout.params)
_TP_G, _TP_DRIFT = _engine.TP_G, _engine.TP_DRIFT
#: an orbit's parameters in the parameter row (GS_TP_MU, GS_TP_ORBIT_R)
_ORBIT_SLOTS = {"orbit_mu": _engine.TP_MU, "orbit_radius": _engine.TP_ORBIT_R}
_build._UNITS.setdefault("m3/s2", {"m": 3, "s": -2})   # orbit_mu's unit (only tree FMUs on an orbit use it)
#: Parameters that must be >= 0 (TreeModel: g, couplings, and these body parameters).
_NONNEG = ("mass", "I1", "I2", "I3", "stiffness", "joint_damping", "damping")
#: A body parameter's slot in the body's block of the parameter row (core/engine/gyrosim_tree.h GS_TB_*).
_BODY_SLOTS = {"mass": _engine.TB_MASS, "I1": _engine.TB_I, "I2": _engine.TB_I + 1, "I3": _engine.TB_I + 2,
               "cm_x": _engine.TB_CM, "cm_y": _engine.TB_CM + 1, "cm_z": _engine.TB_CM + 2,
               "pos_x": _engine.TB_POS, "pos_y": _engine.TB_POS + 1, "pos_z": _engine.TB_POS + 2,
               "stiffness": _engine.TB_STIFF, "rest_angle": _engine.TB_REST, "joint_damping": _engine.TB_DAMP,
               "damping": _engine.TB_DAMP}
_INPUT_SLOTS = {"motor_torque": _engine.TB_MOTOR, "tau_x": _engine.TB_TAU, "tau_y": _engine.TB_TAU + 1,
                "tau_z": _engine.TB_TAU + 2}


@dataclass(frozen=True)
class TreeRow:
    """One FMU variable of a tree scene: its name, :class:`~gyrosim.model.Variable` (None for the model exchange
    locals), what it is to the glue (``kind``: param, max_drift, input, alias, state, output, integrator, max_step,
    work, der), the index that kind takes (a parameter-row slot, an alias row, a state slot, an output column, a
    continuous-state index) and whether it must be >= 0."""

    name: str
    var: object
    kind: str
    index: int = 0
    nonneg: bool = False


def _layout(sc: Scene) -> TreeLayout:
    return TreeLayout(sc.tree, sc.couplings, sc.orbit)


def tree_rows(sc: Scene) -> list[TreeRow]:
    """The variables of tree scene ``sc`` in value-reference order (from 1), each mapped to the glue's kind.

    Raises
    ------
    ConfigError
        A variable the glue cannot map (a variable of :func:`~gyrosim.kernel_tree.tree_variables` unknown here), or
        a start value that is not the engine's start row's (the table would be wrong).
    """
    from ..kernel_tree import tree_output_names, tree_variables

    lay = _layout(sc)
    p0, y0 = lay.params(float(sc.g), float(sc.max_drift)), lay.state()
    aliases = {a.name: i for i, a in enumerate(sc.aliases)}
    couplings = {name: i for i, name in enumerate(sc.coupling_names)}
    columns = {name: i for i, name in enumerate(tree_output_names(sc))}
    rows = []
    for name, v in tree_variables(sc).items():
        bi, short = sc.split_name(name)
        if name == "integrator":
            row = TreeRow(name, v, "integrator")
        elif name == "max_step":
            row = TreeRow(name, v, "max_step")
        elif name == "max_drift":
            row = TreeRow(name, v, "max_drift", _TP_DRIFT)
        elif name == "g":
            row = TreeRow(name, v, "param", _TP_G, True)
        elif name in _ORBIT_SLOTS:
            row = TreeRow(name, v, "param", _ORBIT_SLOTS[name], True)
        elif name in aliases:
            row = TreeRow(name, v, "alias", aliases[name])
        elif name in couplings:
            row = TreeRow(name, v, "param", lay.body_offset(len(sc.tree)) + couplings[name], True)
        elif v.causality == "parameter" and bi is not None and short in _BODY_SLOTS:
            row = TreeRow(name, v, "param", lay.body_offset(bi) + _BODY_SLOTS[short], short in _NONNEG)
        elif v.causality == "input" and bi is not None and short in _INPUT_SLOTS:
            row = TreeRow(name, v, "input", lay.body_offset(bi) + _INPUT_SLOTS[short])
        elif v.causality == "output" and v.start is not None and (bi, short) in lay.coord_slots:
            row = TreeRow(name, v, "state", lay.coord_slots[(bi, short)])
        elif v.causality == "output" and name in columns:
            row = TreeRow(name, v, "output", columns[name])
        else:
            raise ConfigError("variable", name, "a variable the tree FMU's table knows (a parameter, an input, a "
                              "joint coordinate or an output of the engine's row)")
        start = {"param": p0, "max_drift": p0, "state": y0}.get(row.kind)
        if start is not None and float(start[row.index]) != float(v.start):
            raise ConfigError("variable", name, f"a start value equal to the engine's row ({v.start!r} in the "
                              f"variables, {float(start[row.index])!r} in slot {row.index})")
        rows.append(row)
    return rows


def tree_me_rows(sc: Scene, rows: list[TreeRow]) -> list[TreeRow]:
    """Model exchange's local variables after ``rows``: ``energy_expected`` and the derivatives ``der(...)`` of the
    continuous states in their order (the joints' coordinates by state slot, then ``energy_expected``)."""
    nx = _layout(sc).nx
    by_slot = {r.index: r for r in rows if r.kind == "state"}
    states = [by_slot[k].name for k in range(nx)] + [WORK_STATE]
    return [TreeRow(WORK_STATE, None, "work", nx)] + [TreeRow(f"der({s})", None, "der", k)
                                                     for k, s in enumerate(states)]


def _c_string(s: str) -> str:
    return '"' + s.replace("\\", "\\\\").replace('"', '\\"') + '"'


def _nominals(sc: Scene, rows: list[TreeRow]) -> list[float]:
    """Nominal values of the continuous states: 1 for quaternions, angles and positions; the start rate (at least
    1) for rates and velocities; the start energy's size (at least 1 J) for energy_expected."""
    from ..model import Model

    lay = _layout(sc)
    by_slot = {r.index: r for r in rows if r.kind == "state"}
    out = []
    for k in range(lay.nx):
        r = by_slot[k]
        short = r.name.rpartition(".")[2]
        fast = short.startswith(("omega_", "v_")) or short == "rate"
        out.append(max(1.0, abs(float(r.var.start))) if fast else 1.0)
    out.append(max(1.0, abs(float(Model(sc).get("energy")))))
    return out


def _unit_of(sc_rows: list[TreeRow], row: TreeRow) -> str:
    if row.kind == "work":
        return "J"
    if row.kind == "der":
        states = [r for r in sc_rows if r.kind == "state"]
        unit = next((r.var.unit for r in states if r.index == row.index), "J")
        return DER_UNITS[unit]
    return row.var.unit


def range_text(row: TreeRow) -> str:
    """What a value of the parameter of ``row`` must be, as TreeModel's message says it."""
    v = row.var
    return v.range.text(v.unit) + (f" (the range of scene parameter {row.name})" if row.kind == "alias" else "")


def _ranges(rows: list[TreeRow]) -> tuple[list[str], dict[int, int]]:
    """The GS_RANGES rows and, by position in ``rows``, the row of each parameter with a bounded range."""
    table, where = [], {}
    for i, r in enumerate(rows):
        if r.kind not in ("param", "alias") or r.var is None or r.var.type != "Real" or not r.var.range.bounded:
            continue
        rng = r.var.range
        kinds = []
        for bound, open_ in ((rng.min, rng.exclusive_min), (rng.max, rng.exclusive_max)):
            kinds.append(("GS_BOUND_EXCLUSIVE" if open_ else "GS_BOUND_INCLUSIVE") if math.isfinite(bound)
                         else "GS_BOUND_NONE")
        lo = _hexf(rng.min) if math.isfinite(rng.min) else "0.0"
        hi = _hexf(rng.max) if math.isfinite(rng.max) else "0.0"
        where[i] = len(table)
        table.append(f"{{{lo}, {hi}, {kinds[0]}, {kinds[1]}, {_c_string(range_text(r))}}}")
    return table, where


def tree_config_header(sc: Scene, rows: list[TreeRow], me_rows: list[TreeRow], ident: str, token: str,
                       fmi_version: int, integrator: str, fmi_type: str) -> str:
    """The generated ``gyrosim_config.h`` of a tree FMU (see the module's docstring)."""
    lay = _layout(sc)
    p0, y0 = lay.params(float(sc.g), float(sc.max_drift)), lay.state()
    has_me = fmi_type in ("me", "both")
    table = ['{GS_K_TIME, 0, 0, "time", "s", -1}' if fmi_version == 3 else '{GS_K_NONE, 0, 0, "", "", -1}']
    ranges, range_of = _ranges(rows)
    for i, r in enumerate(rows + (me_rows if has_me else [])):
        table.append(f"{{{_KIND_C[r.kind]}, {r.index}, {int(r.nonneg)}, {_c_string(r.name)}, "
                     f"{_c_string(_unit_of(rows, r) or '')}, {range_of.get(i, -1)}}}")
    targets = []
    for ai, a in enumerate(sc.aliases):
        for bi, pn, f in a.sets:
            targets.append(f"{{{ai}, {lay.body_offset(bi) + _BODY_SLOTS[pn]}, {_hexf(f)}, {int(pn in _NONNEG)}, "
                           f"{_c_string(sc.body_names[bi] + '.' + pn)}}}")
    quats = [(lay.coord_slots[(i, "q_w")], b.name) for i, b in enumerate(sc.tree) if (i, "q_w") in lay.coord_slots]

    def arr(values, fmt=_hexf, empty="0.0"):
        return "{" + (", ".join(fmt(v) for v in values) if len(values) else empty) + "}"

    lines = [
        "/* Generated by gyrosim.fmu.tree_fmu: the tree scene's description, variable table and start values. */",
        "#ifndef GYROSIM_CONFIG_H", "#define GYROSIM_CONFIG_H", "",
        "#define GS_TREE 1   /* a tree scene: gyrosim_model.h includes gyrosim_tree_model.h */",
        f"#define FMI_VERSION {fmi_version}",
        f"#define MODEL_IDENTIFIER {ident}",
        f'#define MODEL_IDENTIFIER_STRING "{ident}"',
        f'#define INSTANTIATION_TOKEN "{token}"',
        f"#define GS_SCENE_NAME {_c_string(sc.name)}", "",
        f"#define GS_HAS_CS {int(fmi_type in ('cs', 'both'))}   /* the interfaces: --fmi-type {fmi_type} */",
        f"#define GS_HAS_ME {int(has_me)}", "",
        f"/* the tree: {len(sc.tree)} bodies ({', '.join(sc.body_names)}), {len(sc.couplings)} couplings */",
        "#define GS_TREE_DESC " + arr([int(x) for x in lay.desc], str),
        f"#define GS_SYS_NX {lay.nx}   /* joint coordinates */",
        f"#define GS_SYS_NY {lay.ny}   /* state: coordinates, the work integral, the health monitor */",
        f"#define GS_SYS_NP {lay.np}   /* parameter row */",
        f"#define GS_SYS_NOUT {lay.nout}   /* output row */", "",
        "/* start values: the parameter row (inputs 0) and the state (the monitor's part set at initialisation) */",
        "#define GS_START_P " + arr(p0),
        "#define GS_START_Y " + arr(y0),
        f"#define GS_START_INTEGRATOR_CODE {_engine.METHODS.index(integrator)}   /* {integrator} */",
        f"#define GS_START_MAX_STEP {_hexf(sc.max_step)}   /* {sc.max_step!r} */",
        f"#define GS_START_TOLERANCE {_hexf(sc.tolerance)}   /* {sc.tolerance!r} */", "",
        "/* scene parameters: their start values, and {alias, parameter-row slot, factor, >= 0, target} of every "
        "target (alias -1: none) */",
        f"#define GS_N_ALIASES {len(sc.aliases)}",
        "#define GS_START_ALIASES " + arr([a.value for a in sc.aliases]),
        "#define GS_ALIAS_TARGETS {" + (", ".join(targets) if targets else '{-1, 0, 0.0, 0, ""}') + "}", "",
        "/* the parameters' ranges: {lo, hi, lower bound, upper bound, what the message says} (GS_RANGES row of "
        "each GS_TREE_VARS row) */",
        "#define GS_RANGES {" + (", ".join(ranges) if ranges else
                                 '{0.0, 0.0, GS_BOUND_NONE, GS_BOUND_NONE, "a finite number"}') + "}", "",
        "/* ball and free joints: the slot of q_w in the state and the body's name (-1: none) */",
        "#define GS_QUAT_SLOTS " + arr([k for k, _ in quats], str, "-1"),
        "#define GS_QUAT_BODIES " + arr([n for _, n in quats], _c_string, '""'),
        "/* model exchange: the continuous states' nominal values */",
        "#define GS_NOMINALS " + arr(_nominals(sc, rows)), "",
        "/* value reference -> {kind, index, flags (1: >= 0), name, unit, range (GS_RANGES row, -1: none)} */",
        "#define GS_TREE_VARS { \\\n    " + ", \\\n    ".join(table) + "}",
        "", "#endif", "",
    ]
    return "\n".join(lines)


def _fmt(x) -> str:
    return repr(float(x))


def _jacobian_pattern(sc: Scene, rows: list[TreeRow], seed: int):
    """Where the engine's derivatives are not zero at a generic point (random state, parameters and inputs):
    ``(ddy (nx + 1, nx + n_inputs), dout (nout, nx + n_inputs))`` as booleans, columns the joint coordinates, then the
    input slots of ``rows`` in their order."""
    import numpy as np

    lay = _layout(sc)
    rng = np.random.default_rng(seed)
    p = lay.params(float(sc.g), float(sc.max_drift)).copy()
    slots = [r.index for r in rows if r.kind in ("param", "input")]
    slots += [lay.body_offset(bi) + _BODY_SLOTS[pn] for a in sc.aliases for bi, pn, _ in a.sets]
    for k in slots:
        if k != _TP_DRIFT:
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
    return ddy.T != 0.0, dout.T != 0.0


def tree_dependencies(sc: Scene, rows: list[TreeRow], me_rows: list[TreeRow], has_me: bool) -> dict[int, list[int]]:
    """The ModelStructure's dependencies of a tree FMU: ``{value reference of an output or a state derivative: value
    references of the knowns it depends on}``; the knowns are those of the directional derivatives (the inputs, and
    with model exchange the continuous states). Found from the engine's complex-step derivatives at two generic
    points (random state, parameters and inputs): an entry that is zero at both is zero by the equations' structure.
    As the FMU computes them (gyrosim_tree_model.c): a joint-coordinate output depends on itself; a derivative or a
    derived output that depends on one component of a quaternion depends on all four (it sees q normalised);
    energy_error also on energy_expected."""
    lay = _layout(sc)
    pattern = [_jacobian_pattern(sc, rows, seed) for seed in (1, 2)]
    ddy, dout = pattern[0][0] | pattern[1][0], pattern[0][1] | pattern[1][1]
    state_vr = {r.index: vr for vr, r in enumerate(rows, start=1) if r.kind == "state"}
    input_vr = [vr for vr, r in enumerate(rows, start=1) if r.kind == "input"]
    quats = [lay.coord_slots[(b, "q_w")] for b in range(len(sc.tree)) if (b, "q_w") in lay.coord_slots]
    in_quat = {k + a: k for k in quats for a in range(4)}
    work_vr = len(rows) + 1
    energy_error = lay.nx + 4 * len(sc.tree) + 1

    def knowns(row, raw: bool) -> list[int]:
        out = [vr for j, vr in enumerate(input_vr) if row[lay.nx + j]]
        if has_me:
            cols = {j for j in range(lay.nx) if row[j]}
            if not raw:
                cols |= {in_quat[j] + a for j in cols if j in in_quat for a in range(4)}
            out += [state_vr[j] for j in cols if j in state_vr]
        return sorted(out)

    deps = {}
    for vr, r in enumerate(rows, start=1):
        if r.kind == "state":
            deps[vr] = [vr] if has_me else []
        elif r.kind == "output":
            deps[vr] = knowns(dout[r.index], False) + ([work_vr] if has_me and r.index == energy_error else [])
    if has_me:
        for vr, r in enumerate(me_rows, start=len(rows) + 1):
            if r.kind == "der":
                deps[vr] = knowns(ddy[r.index], r.index in in_quat)
    return deps


def _me_note(sc: Scene) -> str:
    """The model description's words on model exchange for scene ``sc``."""
    joints = {b.joint for b in sc.tree}
    coords = []
    if joints & {"ball", "free_rotation", "free"}:
        coords.append("quaternions and angular velocities")
    if "hinge" in joints:
        coords.append("hinge angles and rates")
    if "free" in joints:
        coords.append("positions and velocities")
    note = ("Model exchange: the continuous states are the joints' coordinates (" + ", ".join(coords) + ") and "
            f"{WORK_STATE} (J, the work-energy balance's E(0) + W), their derivatives the engine's right-hand side; "
            "the host's solver integrates them (integrator, max_step, max_drift and the tolerance act in "
            "co-simulation only).")
    if coords and coords[0].startswith("quaternions"):
        note += (f" |q| of a ball or free joint drifts by the solver's error only: when a completed integrator step "
                 f"finds | |q| - 1 | > {ME_NORM_TOL:g}, the FMU asks for a step event and renormalises q in the event "
                 "update; the derived outputs use q normalised.")
    return note + " No event indicators."


def tree_model_description(sc: Scene, rows: list[TreeRow], me_rows: list[TreeRow], ident: str, token: str,
                           fmi_version: int, integrator: str, sources, fmi_type: str, platforms) -> str:
    """modelDescription.xml of a tree FMU: the variables of ``rows`` (value references from 1; FMI 3.0's time at
    0), and with model exchange ``me_rows`` after them."""

    has_me = fmi_type in ("me", "both")
    kind = {"cs": "co-simulation", "me": "model exchange", "both": "co-simulation and model exchange"}[fmi_type]
    desc = (f"gyrosim {sc.name}: {sc.description or 'a tree of bodies'}. Native FMU (the gyrosim C engine, no "
            f"Python), {kind}; a tree of {len(sc.tree)} bodies ({', '.join(sc.body_names)}) joined by joints; "
            f"integrators {', '.join(TREE_INTEGRATORS)}." + (" " + _me_note(sc) if has_me else "") + " "
            + _platforms_note(platforms))
    me_rows = me_rows if has_me else []
    all_rows = rows + me_rows
    units = {_unit_of(rows, r) for r in all_rows} - {""}
    root = description_head(sc, ident, token, fmi_version, desc, sources, fmi_type, units)
    mv = ET.SubElement(root, "ModelVariables")
    if fmi_version == 3:
        ET.SubElement(mv, "Float64", name="time", valueReference="0", causality="independent",
                      variability="continuous", unit="s", description="simulation time")
    nominals = _nominals(sc, rows) if has_me else []
    state_vr = {r.index: vr for vr, r in enumerate(rows, start=1) if r.kind == "state"}
    outputs, initial_unknowns, derivatives = [], [], []
    for i, r in enumerate(all_rows):
        vr = i + 1   # value reference; also the 1-based index in ModelVariables (FMI 2.0)
        v = r.var
        start, nominal, derivative = None, None, None
        if v is not None:
            attrs = {"name": r.name, "valueReference": str(vr), "causality": v.causality,
                     "variability": v.variability, "description": v.description}
            if v.causality == "output":
                outputs.append(vr)
                if v.start is None:
                    attrs["initial"] = "calculated"
                    initial_unknowns.append(vr)
                else:
                    attrs["initial"] = "exact"
                    start = v.start
            elif v.causality == "parameter":
                attrs["initial"] = "exact"
                start = integrator if v.type == "String" else v.start
            else:
                start = v.start
            if has_me and r.kind == "state" and nominals[r.index] != 1.0:
                nominal = _fmt(nominals[r.index])
            vtype = v.type
        else:
            vtype = "Real"
            if r.kind == "work":
                what = ("the energy the work-energy balance expects, E(0) + W_inputs - W_dissipation (model "
                        "exchange's continuous state of the work; energy_error = energy - energy_expected)")
                if nominals[-1] != 1.0:
                    nominal = _fmt(nominals[-1])
            else:
                state = r.name[4:-1]
                what = f"derivative of {state} (model exchange: the engine's right-hand side)"
                derivative = str(state_vr.get(r.index, len(rows) + 1))
                derivatives.append(vr)
            attrs = {"name": r.name, "valueReference": str(vr), "causality": "local", "variability": "continuous",
                     "description": what}
            if r.kind == "work":
                attrs["initial"] = "calculated"
            initial_unknowns.append(vr)
        unit = _unit_of(rows, r)
        if fmi_version == 2:
            sv = ET.SubElement(mv, "ScalarVariable", attrs)
            t = ET.SubElement(sv, "Real" if vtype == "Real" else "String")
            if derivative is not None:
                t.set("derivative", derivative)
            if start is not None:
                t.set("start", start if isinstance(start, str) else _fmt(start))
            if vtype == "Real" and unit:
                t.set("unit", unit)
            if vtype == "Real" and v is not None:
                range_attributes(t.attrib, v)
            if nominal is not None:
                t.set("nominal", nominal)
        elif vtype == "Real":
            if start is not None:
                attrs["start"] = _fmt(start)
            if unit:
                attrs["unit"] = unit
            if v is not None:
                range_attributes(attrs, v)
            if nominal is not None:
                attrs["nominal"] = nominal
            if derivative is not None:
                attrs["derivative"] = derivative
            ET.SubElement(mv, "Float64", attrs)
        else:
            se = ET.SubElement(mv, "String", attrs)
            ET.SubElement(se, "Start", value=str(start))
    initial_unknowns.sort()
    model_structure(root, fmi_version, outputs, derivatives, initial_unknowns,
                    tree_dependencies(sc, rows, me_rows, has_me))
    ET.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + ET.tostring(root, encoding="unicode") + "\n"
