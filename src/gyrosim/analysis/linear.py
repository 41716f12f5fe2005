"""Small oscillations: the Jacobian of a model from the engine, its linearization about an equilibrium or a steady
motion, normal modes and the stability verdict.

The derivatives are the engine's own, by the complex step (``gs_tree_directional`` in ``core/engine/tree_cs.c``):
exact to round-off, no difference quotient, no step to choose. A one-body scene (``free_body``, ``heavy_top``,
``gyroscope``) is differentiated as the one-body tree it is (a ball joint at the pivot, the centre of mass on body
+z), the same mapping the FMUs' ``GetDirectionalDerivative`` uses, so the two give the same bits.

Three objects:

- :func:`jacobian`: A = d(state derivatives)/d(states), B = .../d(inputs), C = d(outputs)/d(states), D =
  .../d(inputs), in the model's own variables (quaternions as four numbers: the FMUs' continuous states), column
  by column the bits of the model-exchange FMUs' ``GetDirectionalDerivative`` (see :func:`_column`).
- :func:`linearize`: the same about an equilibrium or a steady motion, in minimal coordinates (a quaternion
  becomes the small rotation ``<body>.rot_x..z`` in the body frame, q = q0 (1, rot / 2)), with the motion's
  symmetry taken out (below), and its :class:`Mode` list.
- :func:`normal_modes`: frequencies and shapes of M x'' + C x' + K x = 0 from mass, damping and stiffness matrices.

Steady motions. A spinning top in steady precession, a satellite turning with its orbit, a gyroscope whose rotor
spins are not equilibria: their state moves. They are *relative* equilibria: the motion is a symmetry of the
equations (a turn of the world about the vertical or the orbit normal, a turn of an axisymmetric body about its
axis, a shift of a cyclic hinge angle) applied at constant rates. In coordinates that move with those symmetries
the state is at rest, and the linearization there is ``A - sum_k c_k D xi_k`` (xi_k the symmetry's generator,
c_k its rate, fitted from f(x0) = sum_k c_k xi_k(x0)). Its eigenvalues are the small oscillations about the steady
motion (the nutation of a top, the librations of a satellite) as seen in the moving frame.

Equilibria. ``about="equilibrium"`` sets the rates to 0 and searches the positions where the accelerations vanish
(:func:`_rest_search`: a trust-region Newton method on the generalized forces, whose exact Jacobian the engine
gives with holding joint forces applied), checks that they are round-off there (:data:`EQ_RTOL`) and raises a
:class:`~gyrosim.errors.LinearAlgebraError` where it finds none.
"""
from __future__ import annotations

import cmath
import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..core import _engine
from ..core.tree import BODY_OUTPUTS
from ..errors import ConfigError, LinearAlgebraError

__all__ = ["Jacobian", "Linearization", "Mode", "NormalModes", "jacobian", "linearize", "normal_modes",
           "modes_of", "one_body_tree", "steady_precession"]

#: A relative tolerance: f(x0) fits the symmetries within it (f is computed to about 1e-16 of its terms).
STEADY_RTOL = 1e-8


class Jacobian(NamedTuple):
    """The engine's derivatives at a state: ``A`` (nx, nx), ``B`` (nx, nu), ``C`` (ny, nx), ``D`` (ny, nu) and
    the names of the states, inputs and outputs (rows and columns in that order)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list
    inputs: list
    outputs: list


class Names(NamedTuple):
    states: list
    inputs: list
    outputs: list


#: The last part of a state name that is a rate, not a coordinate: a hinge's ``rate``, a slider's ``velocity``
#: (m/s: the rate of its ``displacement``), a rotating joint's ``omega_x..z``, a free joint's ``v_x..z``.
RATE_NAMES = frozenset(("rate", "velocity", "omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"))


def is_rate(name: str) -> bool:
    """Whether state ``name`` (``<body>.<variable>`` or bare) is a rate (:data:`RATE_NAMES`), not a coordinate
    (an angle, a small rotation, a displacement, a position, an orbit's anomaly)."""
    return name.rpartition(".")[2] in RATE_NAMES


@dataclass
class Mode:
    """One eigenvalue of a linearization (one of each complex pair).

    ``frequency`` is the damped angular frequency |Im lambda| (rad/s), ``natural_frequency`` |lambda|,
    ``damping_ratio`` -Re lambda / |lambda| (1 for a real decaying mode, -1 for a real growing one, NaN for 0),
    ``shape`` the eigenvector by state name (complex; largest component 1)."""

    eigenvalue: complex
    frequency: float
    natural_frequency: float
    damping_ratio: float
    shape: dict = field(repr=False)
    kind: str = ""

    @property
    def period(self) -> float:
        """s; inf for a mode that does not oscillate."""
        return 2 * math.pi / self.frequency if self.frequency > 0 else math.inf

    def _ranked(self):
        """(names, values, the coordinates' indices largest first with the negligible ones (1e-9 of the largest)
        left out, the rates' indices largest first): numpy work, once per mode (the table asks for each mode's
        shape; a 1,000-state linearization has 500 modes of 1,000 components)."""
        got = self.__dict__.get("_rank")
        if got is None or got[0] is not self.shape:
            names = list(self.shape)
            v = np.fromiter(self.shape.values(), dtype=complex, count=len(names))
            a = np.abs(v)
            rate = np.fromiter((is_rate(n) for n in names), dtype=bool, count=len(names))
            disp, rest = np.flatnonzero(~rate), np.flatnonzero(rate)
            disp = disp[np.argsort(-a[disp], kind="stable")]
            rest = rest[np.argsort(-a[rest], kind="stable")]
            if disp.size:
                disp = disp[a[disp] > 1e-9 * a[disp[0]]]
            got = (self.shape, names, v, disp, rest)
            self.__dict__["_rank"] = got
        return got[1:]

    def dominant(self, k: int = 3) -> list:
        """The ``k`` state names with the largest components, coordinates (angles, small rotations, displacements,
        positions) before rates (:func:`is_rate`)."""
        names, _, disp, rest = self._ranked()
        return [names[i] for i in np.concatenate([disp, rest])[:k]]

    def displacement_shape(self) -> dict:
        """The shape's coordinates (not its rates), largest first: the largest 1 and the others relative to it (in
        phase with it, real, for an undamped mode)."""
        names, v, disp, _ = self._ranked()
        if not disp.size:
            return {}
        big = v[disp[0]]
        return {names[i]: complex(v[i] / big) for i in disp}


@dataclass
class Linearization:
    """The linearization of a model about a state. Unpacks as ``A, B, C, D, names`` (docs/trees.md).

    Attributes
    ----------
    A, B, C, D : ndarray
        In minimal coordinates (``names.states``: quaternions as small rotations ``<body>.rot_x..z``).
    names : Names
        ``states``, ``inputs``, ``outputs``.
    about : str
        ``equilibrium``, ``steady motion`` or ``state`` (neither: the instantaneous Jacobian).
    rates : dict
        The steady motion's symmetry rates (rad/s, or the cyclic coordinates' rates), by name.
    modes : list of Mode
        One per eigenvalue pair, slowest first.
    stability : str
        ``unstable``, ``asymptotically stable`` or ``marginally stable`` (no eigenvalue with a positive real part
        beyond round-off, some on the imaginary axis: the linear verdict, which the nonlinear terms decide).
    """

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    names: Names
    about: str
    rates: dict
    modes: list
    stability: str
    jacobian: Jacobian = field(repr=False)
    state: np.ndarray = field(repr=False)
    #: the eigenvalues of A (computed once, with the modes)
    ev: np.ndarray | None = field(default=None, repr=False)
    #: about="equilibrium": how the search went (``steps``, ``residual`` and ``scale`` of the accelerations)
    search: dict | None = field(default=None, repr=False)

    def _tuple(self) -> tuple:
        return (self.A, self.B, self.C, self.D, self.names)

    def __iter__(self):
        return iter(self._tuple())

    def __len__(self) -> int:
        return 5

    def __getitem__(self, k):
        """The tuple ``(A, B, C, D, names)`` it stands for: ``lin[0]`` is A, ``lin[-1]`` the names, slices too."""
        return self._tuple()[k]

    @property
    def eigenvalues(self) -> np.ndarray:
        return self.ev if self.ev is not None else np.linalg.eigvals(self.A)

    def coordinates(self) -> dict:
        """The state linearized about, its coordinates only (angles, displacements, quaternions, positions; not
        the rates), by the engine's state names."""
        return {n: float(x) for n, x in zip(self.jacobian.states, self.state) if not is_rate(n)}

    def oscillations(self) -> list:
        """The modes that oscillate (not the rigid ones: a zero eigenvalue of a symmetry or a conserved quantity,
        which round-off splits by about 1e-8 of the largest), slowest first."""
        return [m for m in self.modes if m.kind.endswith("oscillation")]

    def table(self) -> str:
        """The modes as a plain-text table."""
        rows = [f"{'mode':>4}  {'eigenvalue':>26}  {'frequency rad/s':>15}  {'period s':>11}  {'damping':>8}  "
                "shape (largest components)"]
        for k, m in enumerate(self.modes, 1):
            rigid = m.kind.startswith("rigid")
            re = m.eigenvalue.real if abs(m.eigenvalue.real) > 1e-12 * abs(m.eigenvalue) else 0.0
            ev = "0 (to round-off)" if rigid else f"{re:+.6g} {m.eigenvalue.imag:+.6g}j"
            per = f"{m.period:.6g}" if math.isfinite(m.period) and not rigid else "-"
            z = m.damping_ratio if abs(m.damping_ratio) > 1e-12 else 0.0  # round-off shown as 0
            dr = f"{z:.3g}" if math.isfinite(m.damping_ratio) and not rigid else "-"
            fr = 0.0 if rigid else m.frequency
            ds = m.displacement_shape()
            shape = (", ".join(f"{n} {_component(ds[n])}" for n in list(ds)[:3]) if ds and not rigid
                     else ", ".join(m.dominant()))
            rows.append(f"{k:>4}  {ev:>26}  {fr:>15.8g}  {per:>11}  {dr:>8}  {m.kind}: {shape}")
        return "\n".join(rows)


def _component(v: complex) -> str:
    """A shape component: signed where it is in phase or opposed (real), else its size and phase."""
    if abs(v.imag) <= 1e-6 * abs(v):
        return f"{v.real:+.3g}"
    return f"{abs(v):.3g} at {math.degrees(cmath.phase(v)):+.0f} deg"


@dataclass
class NormalModes:
    """Normal modes of M x'' + C x' + K x = 0: ``frequencies`` (rad/s, ascending; damped frequencies when C is
    given), ``shapes`` (columns; mass-normalised, shapes.T M shapes = 1, when C is None), ``damping_ratios``."""

    frequencies: np.ndarray
    shapes: np.ndarray
    damping_ratios: np.ndarray
    eigenvalues: np.ndarray


# ---------------------------------------------------------------------------------------------------- systems
def one_body_tree(I1, I2, I3, mass, cm_distance, g, damping, tau, max_drift, q, omega):
    """A one-body scene's body as the one-body tree it is: ``(desc, y, p)`` for the tree engine. A ball joint at
    the pivot (the origin), the centre of mass at ``cm_distance`` on body +z, the inertia about the centre of mass
    ``I - mass cm_distance^2`` on the transverse axes (the one-body parameters are about the pivot), ``tau`` the
    external torque (body frame). The FMUs' directional derivatives build the same rows in C."""
    desc = np.array([1, 0, -1, _engine.J_BALL], dtype=np.int32)
    nx, ny, np_, _ = _engine.tree_info(desc)
    p = np.zeros(np_)
    p[_engine.TP_G] = g
    p[_engine.TP_DRIFT] = max_drift
    p[_engine.TP_GDIR + 2] = -1.0
    b = _engine.TP_HEAD
    d = cm_distance
    p[b + _engine.TB_ROT] = 1.0
    p[b + _engine.TB_AXIS + 2] = 1.0
    p[b + _engine.TB_MASS] = mass
    p[b + _engine.TB_CM + 2] = d
    p[b + _engine.TB_I] = I1 - mass * d * d
    p[b + _engine.TB_I + 1] = I2 - mass * d * d
    p[b + _engine.TB_I + 2] = I3
    p[b + _engine.TB_DAMP] = damping
    p[b + _engine.TB_TAU:b + _engine.TB_TAU + 3] = tau
    y = np.zeros((1, ny))
    y[0, 0:4] = q
    y[0, 4:7] = omega
    return desc, y, p


class _Block(NamedTuple):
    desc: np.ndarray
    y: np.ndarray          # (1, ny)
    p: np.ndarray          # (np,)
    states: list           # nx names
    inputs: list           # [(name, [(column, factor), ...])]
    outputs: list          # [(name, index in the engine's output row)]
    roots: list            # [(q index, omega index, r index or None, v index or None, symmetric axis or None)]
    hinges: list           # angle indices
    gravity: bool
    orbit: bool
    closed: bool = False   # loops or gears: the state lives on their manifold (the engine projects onto it)


def _blocks(model, system: int = 0) -> list:
    """The model as independent trees (one for a tree scene; one per body for a one-body scene)."""
    model.initialize()
    if model.scene.kernel == "tree":  # the articulated-body algorithm's rows are the tree's already
        L, sc = model.layout, model.scene
        names = sc.output_names()
        states = names[:L.nx]
        inputs = [(n, model._columns(n)) for n, v in model.variables.items() if v.causality == "input"]
        outputs = [(n, k) for k, n in enumerate(names) if n != "energy_error"]
        roots, hinges = [], []
        for i, b in enumerate(sc.tree):
            if b.joint == "hinge":
                hinges.append(L.coord_slots[(i, "angle")])
            if b.parent == -1:
                if b.joint in ("ball", "free_rotation", "free"):
                    qi = L.coord_slots[(i, "q_w")]
                    wi = L.coord_slots[(i, "omega_x")]
                    ri = L.coord_slots.get((i, "r_x"))
                    vi = L.coord_slots.get((i, "v_x"))
                    leaf = not any(c.parent == i for c in sc.tree)
                    roots.append((qi, wi, ri, vi, _symmetric_axis(b) if leaf else None))
        orbit = getattr(sc, "orbit", None) is not None
        return [_Block(L.desc, model._y[system:system + 1].copy(), model._p[system].copy(), states, inputs,
                       outputs, roots, hinges, float(model._p[system, _engine.TP_G]) != 0.0, orbit, model.closed)]
    blocks = []
    multi = model.n_bodies > 1
    for b in range(model.n_bodies):
        pre = f"{model.body_names[b]}." if multi else ""
        m = model
        desc, y, p = one_body_tree(*m._moments[b], m._mass[b], m._cm[b], m._g[b], m._damping[b], m._tau[b],
                                   m.max_drift, m._y[b, 0:4], m._y[b, 4:7])
        states = [pre + n for n in ("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z")]
        inputs = [(pre + n, [(_engine.TP_HEAD + _engine.TB_TAU + k, 1.0)])
                  for k, n in enumerate(("tau_x", "tau_y", "tau_z")) if n in m.variables
                  and m.variables[n].causality == "input"]
        nx = 7
        outputs = [(s, k) for k, s in enumerate(states)]
        outputs += [(pre + n, nx + len(BODY_OUTPUTS) + k)   # the tree row: y, the body's outputs, the scene's
                    for k, n in enumerate(("energy", "energy_error", "L_x", "L_y", "L_z"))
                    if n != "energy_error"]
        I1, I2, _ = m._moments[b]
        sym = 2 if I1 == I2 else None
        blocks.append(_Block(desc, y, p, states, inputs, outputs, [(0, 4, None, None, sym)], [],
                             m._g[b] * m._mass[b] * m._cm[b] != 0.0, False))
    return blocks


def _symmetric_axis(body) -> int | None:
    """The body axis (0, 1, 2) about which a tree body is axisymmetric (inertia and centre of mass), or None."""
    J = np.asarray(body.inertia, dtype=float)
    c = np.asarray(body.cm, dtype=float)
    for k in (2, 0, 1):
        a, b = [j for j in range(3) if j != k]
        off = [J[i, j] for i in range(3) for j in range(3) if i != j]
        if J[a, a] == J[b, b] and not any(off) and c[a] == 0.0 and c[b] == 0.0:
            return k
    return None


def _derivs(bk: _Block, y=None) -> np.ndarray:
    nx = len(bk.states)
    d = np.zeros(nx + 1)
    _engine.tree_derivatives(bk.desc, bk.y if y is None else y, bk.p.reshape(1, -1), d)
    return d[:nx]


def _quats(bk: _Block) -> list:
    return [k for k, s in enumerate(bk.states) if s.endswith("q_w")]


def _column(bk: _Block, vy: np.ndarray, vp: np.ndarray, prep=None):
    """One column of the Jacobian as the model-exchange FMUs compute it (``gs_directional`` in the FMU glue), to
    the bit: the quaternion rates dq/dt = q (0, omega)/2 and the coordinates as outputs at q as it is, with the
    seed as given; every other row at q normalised, a quaternion's seed projected on the unit sphere's tangent
    ((e_k - q^ q^_k) / |q|): what the engine integrates, whose dynamics see only the rotation q stands for.
    ``prep``: :func:`_prep` of the block (computed here when not given)."""
    quats, nout, idx = _prep(bk) if prep is None else prep
    nx = len(bk.states)
    raw_d, raw_o = np.zeros(nx + 1), np.zeros(nout)
    _engine.tree_directional(bk.desc, bk.y, bk.p, vy, vp, raw_d, raw_o)
    if not quats:  # nothing to normalise: the second evaluation would repeat the first to the bit
        return raw_d[:nx], raw_o[idx]
    y, vn = bk.y.copy(), vy.copy()
    for k in quats:
        q = bk.y[0, k:k + 4]
        nq = np.sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3])
        y[0, k:k + 4] = q / nq
        hot = np.flatnonzero(vy[k:k + 4])
        if hot.size:
            a = int(hot[0])
            vn[k:k + 4] = [((1.0 if j == a else 0.0) - y[0, k + j] * y[0, k + a]) / nq for j in range(4)]
    n_d, n_o = np.zeros(nx + 1), np.zeros(nout)
    _engine.tree_directional(bk.desc, y, bk.p, vn, vp, n_d, n_o)
    inq = np.zeros(nx, dtype=bool)
    for k in quats:
        inq[k:k + 4] = True
    d = np.where(inq, raw_d[:nx], n_d[:nx])
    o = np.where(idx < nx, raw_o[idx], n_o[idx])
    return d, o


def _prep(bk: _Block):
    """What every column of a block's Jacobian shares: its quaternions' first indices, the engine's output count
    and the engine output index of each of the block's outputs (an array: the columns are numpy work, not a
    Python loop over the outputs per column)."""
    return _quats(bk), _engine.tree_info(bk.desc)[3], np.array([i for _, i in bk.outputs], dtype=np.intp)


class _Stages:
    """Reports the work as ``progress(what, done, total)``, stage by stage (the Jacobian's columns, an equilibrium
    search's steps, the eigenvalues); nothing where ``progress`` is None."""

    def __init__(self, progress=None):
        self.progress = progress
        self.what, self.done, self.total = "", 0, 0

    def start(self, what: str, total: int) -> None:
        self.what, self.done, self.total = what, 0, int(total)
        if self.progress is not None:
            self.progress(what, 0, self.total)

    def tick(self, n: int = 1) -> None:
        self.done += n
        if self.progress is not None:
            self.progress(self.what, self.done, self.total)


_QUIET = _Stages()


def _block_jacobian(bk: _Block, progress=None):
    nx = len(bk.states)
    A = np.zeros((nx, nx))
    C = np.zeros((len(bk.outputs), nx))
    B = np.zeros((nx, len(bk.inputs)))
    D = np.zeros((len(bk.outputs), len(bk.inputs)))
    zp = np.zeros(bk.p.shape[0])
    prep = _prep(bk)
    vy = np.zeros(nx)
    for j in range(nx):
        vy[j] = 1.0
        A[:, j], C[:, j] = _column(bk, vy, zp, prep)
        vy[j] = 0.0
        if progress is not None:
            progress()
    for j, (_, cols) in enumerate(bk.inputs):
        vp = np.zeros_like(zp)
        for col, f in cols:
            vp[col] = f
        B[:, j], D[:, j] = _column(bk, np.zeros(nx), vp, prep)
    return A, B, C, D


def jacobian(model, *, system: int = 0) -> Jacobian:
    """The engine's derivatives at the model's current state (:class:`Jacobian`), by the complex step.

    States are the model's coordinates as the engine integrates them (every quaternion as four numbers), inputs
    the model's input variables, outputs its engine outputs (coordinates, world attitudes, energy, L).

    Examples
    --------
    >>> from gyrosim import Model
    >>> J = jacobian(Model("coupled_pendula", parameters={"left.angle": 0.0}))
    >>> J.states
    ['left.angle', 'left.rate', 'right.angle', 'right.rate']
    >>> round(float(J.A[1, 0]), 6)   # -(g/L + k/(m L^2)) = -(9.81 + 0.5)
    -10.31
    """
    return _jacobian_of(_blocks(model, system))


def _jacobian_of(blocks: list, stages: _Stages = _QUIET) -> Jacobian:
    stages.start("Jacobian", sum(len(bk.states) for bk in blocks))
    parts = [(_block_jacobian(bk, stages.tick), bk) for bk in blocks]
    from scipy.linalg import block_diag

    A, B, C, D = (block_diag(*[p[0][k] for p in parts]) for k in range(4))
    return Jacobian(A, B, C, D, [s for _, bk in parts for s in bk.states],
                    [n for _, bk in parts for n, _ in bk.inputs], [n for _, bk in parts for n, _ in bk.outputs])


# ---------------------------------------------------------------------------------------------------- symmetries
def _qleft(a):
    """4x4 matrix of q -> (0, a) (x) q."""
    x, y, z = a
    return np.array([[0, -x, -y, -z], [x, 0, -z, y], [y, z, 0, -x], [z, -y, x, 0]], dtype=float)


def _qright(a):
    """4x4 matrix of q -> q (x) (0, a)."""
    x, y, z = a
    return np.array([[0, -x, -y, -z], [x, 0, z, -y], [y, -z, 0, x], [z, y, -x, 0]], dtype=float)


def _cross(a):
    x, y, z = a
    return np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]], dtype=float)


def _world_turn(bk: _Block, y: np.ndarray):
    """The turn of the world (about the vertical where gravity or an orbit acts, else about the angular
    momentum) as a symmetry of a tree with roots: (xi(x) (nx,), D xi (nx, nx)); an orbit's anomaly turns with it."""
    nx = len(bk.states)
    x = y[0, :nx]
    if bk.gravity or bk.orbit:
        axis = np.array([0.0, 0.0, 1.0])
    else:  # torque-free: the direction of the angular momentum (any axis is a symmetry; this one moves)
        out = np.zeros(_engine.tree_info(bk.desc)[3])
        _engine.tree_outputs(bk.desc, y, bk.p.reshape(1, -1), out)
        L = out[-3:]
        axis = L / np.linalg.norm(L) if np.linalg.norm(L) > 0 else np.array([0.0, 0.0, 1.0])
    Dw = np.zeros((nx, nx))
    for qi, _, ri, vi, _ in bk.roots:
        Dw[qi:qi + 4, qi:qi + 4] = 0.5 * _qleft(axis)
        for k in (ri, vi):
            if k is not None:
                Dw[k:k + 3, k:k + 3] = _cross(axis)
    anomaly = [k for k, s in enumerate(bk.states) if s.endswith("anomaly") and bk.orbit]
    Dw[anomaly, :] = 0.0
    xi = Dw @ x
    xi[anomaly] = 1.0
    return xi, Dw


def _generators(bk: _Block, A: np.ndarray, y: np.ndarray) -> list:
    """The symmetries of this tree at this state: [(name, xi(x0) (nx,), D xi (nx, nx))]."""
    nx = len(bk.states)
    x = y[0, :nx]
    gens = []
    if bk.roots:
        gens.append(("world", *_world_turn(bk, y)))
        for qi, wi, _, _, sym in bk.roots:
            if sym is None:
                continue
            e = np.zeros(3)
            e[sym] = 1.0
            Db = np.zeros((nx, nx))
            Db[qi:qi + 4, qi:qi + 4] = 0.5 * _qright(e)
            Db[wi:wi + 3, wi:wi + 3] = -_cross(e)
            gens.append((bk.states[qi].rpartition(".")[0] + ".spin" if "." in bk.states[qi] else "spin",
                         Db @ x, Db))
    scale = np.max(np.abs(A)) if A.size else 0.0
    for k in bk.hinges:  # a hinge angle the equations do not depend on: shifting it is a symmetry
        if np.all(np.abs(A[:, k]) <= 1e-13 * max(scale, 1e-300)):
            xi = np.zeros(nx)
            xi[k] = 1.0
            gens.append((bk.states[k], xi, np.zeros((nx, nx))))
    return gens


def _reduction(bk: _Block, x: np.ndarray):
    """T (nx, nr): minimal -> engine coordinates at x; P (nr, nx) its left inverse on the tangent space; names."""
    nx = len(bk.states)
    quats = {qi for qi in range(nx) if bk.states[qi].endswith("q_w")}
    cols, names = [], []
    T_blocks, P_rows = [], []
    k = 0
    while k < nx:
        if k in quats:
            q = x[k:k + 4]
            base = bk.states[k][:-len("q_w")]
            for a in range(3):
                e = np.zeros(3)
                e[a] = 1.0
                col = np.zeros(nx)
                col[k:k + 4] = 0.5 * (_qright(e) @ q)  # dq = q (x) (0, rot) / 2
                T_blocks.append(col)
                row = np.zeros(nx)
                row[k:k + 4] = 2.0 * (_qright(e) @ q) / (q @ q)  # rot_a = 2 <q (x) e_a, dq> / |q|^2
                P_rows.append(row)
                names.append(f"{base}rot_{'xyz'[a]}")
            k += 4
        else:
            col = np.zeros(nx)
            col[k] = 1.0
            T_blocks.append(col)
            P_rows.append(col.copy())
            names.append(bk.states[k])
            k += 1
        cols.append(k)
    return np.array(T_blocks).T, np.array(P_rows), names


def _state_from(model, about, stages: _Stages = _QUIET) -> dict | None:
    """Set the model to the state ``about`` asks for; about="equilibrium": how the search went."""
    if isinstance(about, dict):
        model.set_values(about)   # checked together: the order of the names does not matter
        model.initialize()
    elif about == "steady_precession":
        steady_precession(model)
    elif about == "equilibrium":
        return _to_equilibrium(model, stages)
    return None


def steady_precession(model, *, theta: float | None = None, spin: float | None = None,
                      branch: str = "slow") -> dict:
    """Set a one-body symmetric top on a pivot (heavy_top, gyroscope) to steady precession at nutation angle
    ``theta`` (rad; default its present one) and spin ``spin`` (omega_z, rad/s; default its present one): the
    precession rate phi' solving I1 cos(theta) phi'^2 - I3 omega_z phi' + m g l = 0 (``branch`` ``slow`` or
    ``fast``; theta = 0 is the sleeping top). Returns the rates ``phi_dot``, ``psi_dot``."""
    if model.scene.kernel != "body" or model.n_bodies != 1:
        raise ConfigError("about", "steady_precession", "a one-body symmetric top on a pivot (heavy_top, "
                          "gyroscope); for a tree set the rates and use about='steady'")
    I1, I2, I3 = (float(v) for v in model._moments[0])
    mgl = float(model._mass[0] * model._g[0] * model._cm[0])
    if I1 != I2 or mgl == 0.0:
        raise ConfigError("about", "steady_precession", f"a symmetric top (I1 = I2; here {I1}, {I2}) with gravity "
                          f"acting (mass*g*cm_distance = {mgl})")
    if branch not in ("slow", "fast"):
        raise ConfigError("branch", branch, "slow or fast")
    theta = model.get("theta") if theta is None else float(theta)
    w3 = model.get("omega_z") if spin is None else float(spin)
    if not (0.0 <= theta <= math.pi):
        raise ConfigError("theta", theta, "an angle in [0, pi] rad")
    c, s = math.cos(theta), math.sin(theta)
    if s < 1e-12:
        for n, v in zip(("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"),
                        (1.0, 0.0, 0.0, 0.0, 0.0, 0.0, w3) if c > 0 else (0.0, 1.0, 0.0, 0.0, 0.0, 0.0, w3)):
            model.set(n, v)
        model.initialize()
        return {"phi_dot": 0.0, "psi_dot": w3}
    disc = (I3 * w3) ** 2 - 4 * I1 * c * mgl
    if disc < 0:
        raise ConfigError("omega_z", w3, f"a spin fast enough for steady precession at theta = {theta:.6g} rad: "
                          f"(I3 omega_z)^2 >= 4 I1 m g l cos(theta) = {4 * I1 * c * mgl:.6g}")
    if abs(c) < 1e-15:
        pd = mgl / (I3 * w3)
    else:
        r = math.sqrt(disc)
        # the slow root written without cancellation: 2 m g l / (I3 w3 + sign r)
        slow = 2 * mgl / (I3 * w3 + math.copysign(r, I3 * w3))
        fast = (I3 * w3 + math.copysign(r, I3 * w3)) / (2 * I1 * c)
        pd = slow if branch == "slow" else fast
    from ..core.rotations import euler_zyz_rates_to_omega_body, euler_zyz_to_quat

    q = euler_zyz_to_quat(0.0, theta, 0.0)
    w = euler_zyz_rates_to_omega_body(0.0, theta, 0.0, pd, 0.0, w3 - pd * c)
    for n, v in zip(("q_w", "q_x", "q_y", "q_z", "omega_x", "omega_y", "omega_z"), (*q, *w)):
        model.set(n, float(v))
    model.initialize()
    return {"phi_dot": pd, "psi_dot": w3 - pd * c}


def _inert_bodies(model) -> list:
    """The tree bodies of ``model`` with no inertia at their joint (``model.inert_bodies()``; none on the one-body
    kernel, whose moments are checked > 0)."""
    return model.inert_bodies()


def _check_finite(model, blocks, A=None) -> None:
    """Refuse a state where the equations of motion are singular (their derivatives, or their Jacobian ``A``, not
    finite) with one line that names the cause: a body with no inertia at its joint (the parameter and its value),
    else the state (exit code 2: the parameters and the state are the user's)."""
    bad = []
    for bk in blocks:
        f = _derivs(bk)
        bad += [bk.states[k] for k in np.flatnonzero(~np.isfinite(f))]
    if not bad and A is not None:
        rows = ~np.all(np.isfinite(A), axis=1)
        names = [s for bk in blocks for s in bk.states]
        bad = [names[k] for k in np.flatnonzero(rows)]
    if not bad:
        return
    where = (f"the derivatives of {', '.join(bad[:6])}{', ...' if len(bad) > 6 else ''} are not finite at this "
             "state")
    for name, value, what, alone, advice in _inert_bodies(model):
        how = ("nothing resists its joint's acceleration: the equations of motion are singular" if alone else
               "the equations of motion are singular where the bodies below it line up with its joint, as here")
        raise ConfigError(name, value, f"a body with inertia at its joint: {what}, so {how} ({where}); {advice}")
    raise ConfigError("state", "the start state", f"a state where the equations of motion are regular: {where} (a "
                      "singular configuration, such as gimbal lock between massless gimbals); start elsewhere or "
                      "give the bodies inertia")


#: The equilibrium search's verdict: the accelerations where it stops, over their scale (the largest of those at
#: the start and of the acceleration a unit change of the positions makes, the Frobenius norm of their Jacobian),
#: must be at most this. The accelerations are sums of terms computed to ~1e-16 of their size, and Newton's last
#: step lands within the stiffness's conditioning of round-off of the root: seen at most 3e-16 (pendula, tops, the
#: embedded scenes, chains of 20 to 500 links started bent); the turned hinge of issue 43, which the old search
#: called an equilibrium, was at 7e-3, and a search that stalls stops far above this too.
EQ_RTOL = 1e-10


def _unit_of(name: str, length: float, n_orb: float) -> float:
    """The trust region's unit for the coordinate ``name`` (minimal coordinates): 1 rad for an angle or a small
    rotation, the scene's length for a displacement or a position; on an orbit its rate for a rate."""
    last = name.rpartition(".")[2]
    if last in ("velocity", "v_x", "v_y", "v_z"):
        return length * n_orb
    if is_rate(name):
        return n_orb
    if last == "displacement" or last in ("r_x", "r_y", "r_z"):
        return length
    return 1.0


def _length_scale(model) -> float:
    """The scene's length (m): its largest joint offset or centre of mass distance, 1 m where it has none."""
    tree = getattr(model.scene, "tree", None) or []
    ls = [float(np.linalg.norm(v)) for b in tree for v in (b.pos, b.cm)]
    ls = [v for v in ls if v > 0]
    return max(ls) if ls else 1.0


def _project(bk: _Block, x: np.ndarray) -> np.ndarray:
    """``x`` moved onto the manifold of the block's loops and gears, as the engine assembles a start
    (``gs_tree_start``: the positions by Gauss-Newton on the loops' residuals, then the rates by the velocity
    impulse; projection.h); ``x`` itself where the block has none."""
    if not bk.closed:
        return x
    y = _with(bk, x)
    _engine.tree_start(bk.desc, y, bk.p.reshape(1, -1))
    return y[0, :len(x)].copy()


def _tangent(bk: _Block, x: np.ndarray, length: float):
    """(T, L): an orthonormal basis T (nr, m) of the tangent space of the loops' and gears' manifold at ``x`` (on
    it), in the minimal coordinates of :func:`_reduction`, and L = T^T Pi (m, nr), Pi the derivative of the
    engine's projection there. Pi is a projector (Pi^2 = Pi) whose range is the tangent space and whose kernel is
    the set of directions the projection removes, so L T = I and L kills that kernel: A = Df Pi in the basis
    (T, kernel) is [[L A T, 0], [*, 0]], and the mechanism's own linear dynamics is R = L A T (m x m), the 2 x rank
    zero eigenvalues of the directions across the manifold left out.

    Pi by central differences of the projection, a step of 1e-6 of each coordinate's unit (1 rad, the scene's
    length; a rate's unit 1/s times those): the projection converges to 1e-15 of the residuals' scale, so each
    column is good to about 1e-9, and only the subspace is taken from it (its singular values are 0 across the
    manifold and at least 1 along it: the gap decides the dimension)."""
    _, P, names = _reduction(bk, x)
    nr = len(names)
    Pi = np.zeros((nr, nr))
    for j, n in enumerate(names):
        last = n.rpartition(".")[2]
        h = 1e-6 * (length if last in ("displacement", "velocity") or last[:2] in ("r_", "v_") else 1.0)
        dz = np.zeros(nr)
        dz[j] = h
        xp = _project(bk, _retract(bk, x, dz))
        xm = _project(bk, _retract(bk, x, -dz))
        Pi[:, j] = P @ (xp - xm) / (2 * h)
    T = _range_basis(Pi)
    return T, T.T @ Pi


def _range_basis(P: np.ndarray) -> np.ndarray:
    """An orthonormal basis of the range of the projector (or a block of it) P: the left singular vectors whose
    singular values are above 1e-3 of the largest (a projector's are 0 across the manifold and at least 1 along it,
    a block's near those: the gap decides the dimension)."""
    U, sv, _ = np.linalg.svd(P)
    return U[:, :int(np.sum(sv > 1e-3 * max(float(sv[0]), 1e-300)))] if sv.size else np.zeros((P.shape[0], 0))


def _retract(bk: _Block, x: np.ndarray, dz: np.ndarray) -> np.ndarray:
    """The state ``x`` (engine coordinates) moved by ``dz`` in the minimal coordinates of :func:`_reduction`: a
    quaternion turned by its small rotation (q <- q (x) exp(rot / 2), normalised), every other coordinate added."""
    x = x.copy()
    quats = set(_quats(bk))
    k = m = 0
    while k < len(x):
        if k in quats:
            rot = dz[m:m + 3]
            th = float(np.linalg.norm(rot))
            w, v = math.cos(th / 2), (0.5 if th < 1e-8 else math.sin(th / 2) / th) * rot
            q = w * x[k:k + 4] + _qright(v) @ x[k:k + 4]
            x[k:k + 4] = q / np.linalg.norm(q)
            k, m = k + 4, m + 3
        else:
            x[k] += dz[m]
            k, m = k + 1, m + 1
    return x


def _tr_step(Js: np.ndarray, r: np.ndarray, delta: float):
    """The trust-region step: u minimising |r + Js u| with |u| <= delta (Levenberg-Marquardt: u(lam) = -(Js^T Js
    + lam)^-1 Js^T r, lam >= 0 the smallest that keeps |u| <= delta), from the SVD of Js. Directions of singular
    values below 1e-12 of the largest are left alone: the accelerations do not depend on them (a cyclic
    coordinate, a turn about the vertical, a rigid translation), so the step does not wander along them."""
    U, sig, Vt = np.linalg.svd(Js, full_matrices=False)
    if not sig.size or sig[0] == 0.0:
        return np.zeros(Js.shape[1])
    keep = sig > 1e-12 * sig[0]
    sig, V, b = sig[keep], Vt[keep].T, U[:, keep].T @ r
    c = sig * b

    def u_of(lam):
        return -(c / (sig * sig + lam))

    w = u_of(0.0)
    if np.linalg.norm(w) <= delta:
        return V @ w
    lo, hi = 0.0, float(np.linalg.norm(c)) / delta  # |u(hi)| <= |c| / hi = delta
    lam = lo
    for _ in range(60):  # Newton on 1/|u(lam)| - 1/delta, nearly linear in lam, kept inside [lo, hi]
        w = u_of(lam)
        nw = float(np.linalg.norm(w))
        if abs(nw - delta) <= 1e-3 * delta:
            break
        if nw > delta:
            lo = lam
        else:
            hi = lam
        d = float(np.sum(c * c / (sig * sig + lam) ** 3)) / nw ** 3
        step = (1.0 / nw - 1.0 / delta) / d if d > 0 else -1.0
        lam = lam + step if lo < lam + step < hi else 0.5 * (lo + hi)
    return V @ u_of(lam)


class _Search(NamedTuple):
    x: np.ndarray          # the engine state where it stopped
    steps: int
    residual: float        # max |acceleration| there (the minimal coordinates' rates of change)
    scale: float           # their scale (EQ_RTOL)
    worst: str             # the state whose rate of change is largest there
    value: float           # that rate of change
    flat: bool             # no step of the positions changes the accelerations there (to first order)


def _newton_step(Js: np.ndarray, r: np.ndarray):
    """The Newton step -Js^-1 r by LU where Js is square and well conditioned (LAPACK's estimate of its reciprocal
    condition number above 1e-10), else None (then :func:`_tr_step`'s SVD): a 500 x 500 LU in milliseconds where
    the SVD takes seconds."""
    if not Js.size or Js.shape[0] != Js.shape[1]:
        return None
    import warnings

    from scipy.linalg import LinAlgWarning, lu_factor, lu_solve
    from scipy.linalg.lapack import dgecon

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", LinAlgWarning)
        lu, piv = lu_factor(Js, check_finite=False)
    rcond, info = dgecon(lu, float(np.max(np.sum(np.abs(Js), axis=0))), norm="1")
    if info != 0 or not rcond > 1e-10:
        return None
    u = -lu_solve((lu, piv), r, check_finite=False)
    return u if np.all(np.isfinite(u)) else None


def _hold_seeds(bk: _Block, x: np.ndarray):
    """Parameter seeds (k, np) of a generalized force on each joint coordinate of ``bk`` at the state ``x``, in the
    order of the coordinates: a hinge's or a slider's motor (on the child, its reaction on the parent), a ball's
    torque about each body axis (the body's external torque, its opposite on the parent). None where a joint has
    none (a free joint's translation) or on an orbit."""
    from ..core.rotations import quat_to_matrix

    if bk.orbit:
        return None
    nb = int(bk.desc[0])
    parents = [int(bk.desc[2 + 2 * i]) for i in range(nb)]
    joints = [int(bk.desc[3 + 2 * i]) for i in range(nb)]
    seeds, at = [], 0
    for i, (par, j) in enumerate(zip(parents, joints)):
        o = _engine.TP_HEAD + _engine.TB_NP * i
        if j in (_engine.J_HINGE, _engine.J_SLIDER):
            s = np.zeros(bk.p.shape[0])
            s[o + _engine.TB_MOTOR] = 1.0
            seeds.append(s)
            at += 2
        elif j == _engine.J_BALL:
            q = x[at:at + 4] / np.linalg.norm(x[at:at + 4])
            R = quat_to_matrix(bk.p[o + _engine.TB_ROT:o + _engine.TB_ROT + 4]) @ quat_to_matrix(q)  # child -> parent
            for c in range(3):
                s = np.zeros(bk.p.shape[0])
                s[o + _engine.TB_TAU + c] = 1.0
                if par >= 0:
                    op = _engine.TP_HEAD + _engine.TB_NP * par
                    s[op + _engine.TB_TAU:op + _engine.TB_TAU + 3] = -R[:, c]
                seeds.append(s)
            at += 7
        elif j == _engine.J_FIXED:
            continue
        else:
            return None
    return np.array(seeds).reshape(len(seeds), bk.p.shape[0])


def _rest_search(bk: _Block, length: float, n_orb: float = 0.0, max_steps: int = 200,
                 stages: _Stages = _QUIET) -> _Search:
    """A trust-region Newton search for a state of ``bk`` whose accelerations vanish (on a circular orbit: whose
    rates of change equal the turn with the orbit frame at rate ``n_orb``), moving its coordinates (on an orbit its
    rates too; never an orbit's anomaly) from the block's state; the rates stay as they are (0 at an equilibrium).

    The equations solved are the generalized forces Q(q) = M(q) a(q) = 0 (the accelerations' roots), whose
    Jacobian, the stiffness, comes exactly from the engine's: with joint forces -Q(q_k) added that hold the state
    at rest (a motor on each hinge and slider, a torque on each ball joint), the accelerations' Jacobian there is
    M^-1 dQ/dq (the term in dM/dq multiplies the accelerations, now 0), and M^-1 the accelerations' derivatives
    by those forces. Newton on Q, not on a: a bent chain of light links has accelerations far from linear in the
    angles (M^-1 varies), its forces nearly linear (the gravity of a chain hanging near straight); Newton on a from
    such a start wanders, on Q it converges in a few steps. Where the joints cannot all be held (a free joint, an
    orbit), the plain accelerations and their Jacobian.

    Each step solves the linearized equations within a trust region (no coordinate moved by more than its radius;
    units: 1 rad for angles and rotations, the scene's ``length`` for displacements) and is taken only where the
    residual shrinks as the linear model says; the region grows after good steps and shrinks after poor ones, so a
    Jacobian singular at the start (a pendulum started horizontal, where the torque's derivative vanishes) gives a
    step of the region's size, not a jump of 1e15 rad. Where the Jacobian is round-off (the start a turning point of
    the forces: a pendulum exactly horizontal) or no step helps and the accelerations are not yet round-off, a step
    along the accelerations (where the motion from rest goes: downhill in the potential), else a probe of each
    coordinate by a quarter of its unit either way, looks for a way off the plateau."""
    nx = len(bk.states)
    _, _, names = _reduction(bk, bk.y[0, :nx])
    if n_orb:
        unknown = [k for k, n in enumerate(names) if not n.endswith("anomaly")]
        rows = unknown
    else:
        unknown = [k for k, n in enumerate(names) if not is_rate(n) and not n.endswith("anomaly")]
        rows = [k for k, n in enumerate(names) if is_rate(n)]  # the accelerations (the coordinates' rows: rates, 0)
    units = np.array([_unit_of(names[k], length, n_orb) for k in unknown])
    plain = not _quats(bk)
    engine, k = [], 0  # the engine index of each minimal coordinate (-1: a small rotation, 3 per quaternion)
    for q in _quats(bk) + [nx]:
        engine += list(range(k, q)) + ([-1, -1, -1] if q < nx else [])
        k = q + 4
    rates_at = np.array([engine[k] for k in rows]) if not n_orb else None  # the rates' rows are the engine's

    def at(x, p=None):
        return bk._replace(y=_with(bk, x), p=bk.p if p is None else p)

    def minimal(b, x, d):
        if rates_at is not None:
            return d[rates_at]
        return (d if plain else _reduction(b, x)[1] @ d)[rows]

    def accel(x):
        b = at(x)
        f = _derivs(b)
        if n_orb:
            f = f - n_orb * _world_turn(b, b.y)[0]
        return minimal(b, x, f)

    def jac(x, p=None):
        b = at(x, p)
        if plain and not n_orb:  # only the coordinates' columns: half the engine's work
            A = np.zeros((nx, len(unknown)))
            prep = _prep(b)
            zp = np.zeros(b.p.shape[0])
            for j, k in enumerate(unknown):
                vy = np.zeros(nx)
                vy[k] = 1.0
                A[:, j] = _column(b, vy, zp, prep)[0]
                stages.tick()
            return A[rows] * units
        A = _block_jacobian(b, stages.tick)[0]
        if n_orb:
            A = A - n_orb * _world_turn(b, b.y)[1]
        if not plain:
            T, P, _ = _reduction(b, x)
            A = P @ A @ T
        return A[np.ix_(rows, unknown)] * units

    def forces(x, a):
        """(hold, r): where the joints can be held, hold = (the seeds, M^-1 factored) and r = Q = M a, the
        generalized forces, by LU on M^-1 (M is as ill-conditioned as the tree makes it, 8e10 for 500 point masses
        on light links: solved, never inverted and multiplied); else (None, a). Not with loops or gears: their
        rows take up part of any holding force, M^-1 on their manifold is singular and Q = M a undefined; there
        the plain accelerations (which vanish at the same states)."""
        seeds = None if n_orb or bk.closed else _hold_seeds(bk, x)
        if seeds is None or not len(seeds) == len(unknown) == len(rows):
            return None, a
        from scipy.linalg import lu_factor, lu_solve

        b = at(x)
        prep, zy = _prep(b), np.zeros(nx)
        Binv = np.empty((len(rows), len(seeds)))  # M^-1: the accelerations per unit generalized force
        for j, sd in enumerate(seeds):
            Binv[:, j] = minimal(b, x, _column(b, zy, sd, prep)[0])
            stages.tick()
        if not np.all(np.isfinite(Binv)):
            return None, a
        import warnings

        from scipy.linalg import LinAlgWarning

        with np.errstate(all="ignore"), warnings.catch_warnings():
            warnings.simplefilter("ignore", LinAlgWarning)  # singular: Q not finite, below
            lu = lu_factor(Binv, check_finite=False)
            Q = lu_solve(lu, a, check_finite=False)
        return ((seeds, lu), Q) if np.all(np.isfinite(Q)) else (None, a)

    def local(x, a):
        """(hold, r, Js, Ja) at x: the residual (the generalized forces where the joints can be held, else the
        accelerations), its Jacobian in the trust region's units (dQ/dq = M J~, J~ the accelerations' Jacobian
        with the holding forces -Q applied) and the accelerations' Jacobian."""
        evals[0] += 1
        seeds = None if n_orb or bk.closed else _hold_seeds(bk, x)  # (as forces())
        held = seeds is not None and len(seeds) == len(unknown) == len(rows)
        stages.start(f"equilibrium search, Jacobian {evals[0]}", (len(seeds) if held else 0)
                     + (len(unknown) if plain and not n_orb else nx))
        hold, r = forces(x, a) if held else (None, a)
        if hold is None:
            Ja = jac(x)
            return None, a, Ja, Ja
        from scipy.linalg import lu_solve

        seeds, lu = hold
        Ja = jac(x, bk.p - seeds.T @ r)
        return hold, r, lu_solve(lu, Ja, check_finite=False), Ja

    def merit(x_try, a_try, hold):
        """The residual at a trial point, as the step's model measures it."""
        if hold is None:
            return a_try
        stages.start(f"equilibrium search, forces {evals[0]}", len(unknown))
        h, r_try = forces(x_try, a_try)
        return r_try if h is not None else np.full_like(r_try, np.nan)

    def size(v):
        return float(np.max(np.abs(v), initial=0.0))

    def move(x, u):
        dz = np.zeros(len(names))
        dz[unknown] = u * units
        return _retract(bk, x, dz)

    x = bk.y[0, :nx].copy()
    a = accel(x)
    steps, evals = 0, [0]
    if size(a) == 0.0 or not unknown:  # at rest already (a chain hanging straight), or nothing to move
        k = int(np.argmax(np.abs(a))) if a.size else 0
        return _Search(x, 0, size(a), size(a), names[rows[k]] if a.size else "", float(a[k]) if a.size else 0.0,
                       True)
    hold, r, Js, Ja = local(x, a)
    # the accelerations' scale: those at the start, and what a unit change of the coordinates makes (the Frobenius
    # norm of their Jacobian: within sqrt(n) of its largest singular value, without an SVD)
    scale = max(size(a), float(np.linalg.norm(Ja)))
    delta, probes = 0.5, 0
    while steps < max_steps:
        rr = float(r @ r)
        if size(a) <= 1e-15 * scale:
            break
        # a Jacobian of round-off (the residual's change over a unit below 1e-10 of it) gives no direction
        if float(np.linalg.norm(Js)) > 1e-10 * math.sqrt(rr):
            u = _newton_step(Js, r)
            if u is not None and size(u) <= delta:
                pred = rr
            else:  # beyond the region, singular or ill-conditioned: Levenberg-Marquardt within the region
                u = _tr_step(Js, r, delta)
                pred = rr - float(np.sum((r + Js @ u) ** 2))
            nu, ok, rho = size(u), False, -1.0
            if nu > 0:
                x_try = move(x, u)
                a_try = accel(x_try)
                r_try = merit(x_try, a_try, hold)
                if np.all(np.isfinite(r_try)):
                    act = rr - float(r_try @ r_try)
                    rho = act / pred if pred > 0 else (1.0 if act > 0 else -1.0)
                    ok = act > 0 and rho > 1e-4
                if ok:
                    x, a = x_try, a_try
                    hold, r, Js, Ja = local(x, a)
                    steps += 1
                    if rho > 0.75 and nu > 0.99 * delta:
                        delta = min(2.0 * delta, 1e6)
                if rho < 0.25:
                    delta = 0.25 * nu
            if ok or (nu > 1e-12 and delta > 1e-12):
                continue
        # stalled (no step within the trust region helps) or flat (the start a turning point of the forces, a
        # pendulum horizontal): let it fall, a step along its accelerations (downhill in the potential, where the
        # motion from rest would go), else probe each coordinate either way
        if size(a) <= EQ_RTOL * scale or probes >= 4:
            break
        probes += 1  # (measured by the accelerations themselves: a probe is an evaluation, not a Jacobian)
        best, best_x, best_a = float(a @ a), None, None
        if len(rows) == len(unknown) and not n_orb:  # the rates' rows in the coordinates' order
            fall = a / units
            for h in (0.5, 0.25, 0.125, 0.0625):
                xp = move(x, h / size(fall) * fall)
                ap = accel(xp)
                if np.all(np.isfinite(ap)) and ap @ ap < (1 - 1e-6) * best:
                    best, best_x, best_a = float(ap @ ap), xp, ap
                    break
        for j in range(len(unknown) if best_x is None else 0):
            for sgn in (1.0, -1.0):
                e = np.zeros(len(unknown))
                e[j] = 0.25 * sgn
                xp = move(x, e)
                ap = accel(xp)
                if np.all(np.isfinite(ap)) and ap @ ap < (1 - 1e-6) * best:
                    best, best_x, best_a = float(ap @ ap), xp, ap
        if best_x is None:
            break
        x, a, delta = best_x, best_a, 0.5
        hold, r, Js, Ja = local(x, a)
        steps += 1
    scale = max(scale, float(np.linalg.norm(Ja)))
    worst = int(np.argmax(np.abs(a)))
    flat = float(np.max(np.abs(Ja))) <= 1e-12 * scale
    return _Search(x, steps, size(a), scale, names[rows[worst]], float(a[worst]), flat)


def _rest_search_closed(bk: _Block, length: float, max_steps: int = 200,
                        stages: _Stages = _QUIET) -> _Search:
    """:func:`_rest_search` for a mechanism with loops or gears: a trust-region Newton search that moves along
    their manifold. At rest the tangent space splits into the positions' (Tq: the range of the projection's
    derivative on the positions) and the rates' (Tv: on the rates; Tv = Tq for loops, smaller than all rates
    for gears); the constrained accelerations lie in Tv. The unknowns are the m = dim Tq tangent coordinates,
    the residual the accelerations' m components r = Tv^T a, its Jacobian Tv^T (da/dq) Tq by the complex step
    along Tq's columns (m columns, not one per coordinate). A step moves the positions along Tq and projects back
    onto the loops; it is taken where the residual shrinks and the projection moved the state by less than a
    tenth of the step: a large step could land on another branch of the mechanism's configurations (the
    Bricard's, through its flat position), whose rest states are not this mechanism's motion."""
    nx = len(bk.states)
    x = _project(bk, bk.y[0, :nx].copy())
    _, _, names = _reduction(bk, x)
    pos = [k for k, n in enumerate(names) if not is_rate(n)]
    vel = [k for k, n in enumerate(names) if is_rate(n)]
    zp = np.zeros(bk.p.shape[0])

    def at(x):
        return bk._replace(y=_with(bk, x))

    def accel(x):
        b = at(x)
        return (_reduction(b, x)[1] @ _derivs(b))[vel]

    def frame(x):
        """(Tq, Tv, J): the tangent bases at rest and the residual's Jacobian in Tq's coordinates."""
        T, L = _tangent(bk, x, length)
        Pi = T @ L
        Tq, Tv = _range_basis(Pi[np.ix_(pos, pos)]), _range_basis(Pi[np.ix_(vel, vel)])
        b = at(x)
        Tr, P, _ = _reduction(b, x)
        prep = _prep(b)
        stages.start(f"equilibrium search, Jacobian {evals[0]}", Tq.shape[1])
        J = np.zeros((Tv.shape[1], Tq.shape[1]))
        for j in range(Tq.shape[1]):
            dz = np.zeros(len(names))
            dz[pos] = Tq[:, j]
            J[:, j] = Tv.T @ (P @ _column(b, Tr @ dz, zp, prep)[0])[vel]
            stages.tick()
        evals[0] += 1
        return Tq, Tv, J

    def size(v):
        return float(np.max(np.abs(v), initial=0.0))

    evals, steps = [0], 0
    a = accel(x)
    Tq, Tv, J = frame(x)
    scale = max(size(a), float(np.linalg.norm(J)))
    delta = 0.25
    while steps < max_steps and size(a) > 1e-15 * scale and Tq.shape[1]:
        r = Tv.T @ a
        rr = float(r @ r)
        u = _newton_step(J, r)
        if u is None or size(u) > delta:
            u = _tr_step(J, r, delta)
        pred = rr - float(np.sum((r + J @ u) ** 2))
        dz = np.zeros(len(names))
        dz[pos] = Tq @ u
        step = size(dz)
        if not step > 1e-14:
            break
        x_lin = _retract(bk, x, dz)
        x_try = _project(bk, x_lin)
        a_try = accel(x_try)
        ok = False
        if np.all(np.isfinite(a_try)) and size(x_try - x_lin) <= 0.1 * step:
            r_try = Tv.T @ a_try
            act = rr - float(r_try @ r_try)
            ok = act > 0 and (pred <= 0 or act / pred > 1e-4)
        if ok:
            x, a = x_try, a_try
            Tq, Tv, J = frame(x)
            steps += 1
            delta = min(2.0 * delta, 1.0) if step > 0.99 * delta else delta
        else:
            delta = 0.25 * step
    worst = int(np.argmax(np.abs(a))) if a.size else 0
    flat = float(np.max(np.abs(J), initial=0.0)) <= 1e-12 * scale
    return _Search(x, steps, size(a), scale, names[vel[worst]] if a.size else "",
                   float(a[worst]) if a.size else 0.0, flat)


def _wrap_angles(bk: _Block, x: np.ndarray, scale: float) -> np.ndarray:
    """Hinge angles beyond half a turn wrapped into (-pi, pi] where the equations do not see the turn (no spring,
    no stop: the rates of change the same to round-off)."""
    f0 = _derivs(bk._replace(y=_with(bk, x)))
    for k in bk.hinges:
        if abs(x[k]) > math.pi:
            xw = x.copy()
            xw[k] = math.remainder(x[k], 2 * math.pi)
            fw = _derivs(bk._replace(y=_with(bk, xw)))
            if np.max(np.abs(fw - f0), initial=0.0) <= 1e-12 * max(scale, np.max(np.abs(f0), initial=0.0)):
                x = xw
    return x


def _with(bk: _Block, x: np.ndarray) -> np.ndarray:
    y = bk.y.copy()
    y[0, :len(x)] = x
    return y


def _to_equilibrium(model, stages: _Stages = _QUIET) -> dict:
    """:func:`_move_to_equilibrium`, the model put back as it was where no equilibrium is found (or the state is
    refused)."""
    state = model.get_state()
    try:
        return _move_to_equilibrium(model, stages)
    except np.linalg.LinAlgError as e:  # an SVD or a factorization that did not converge: a run-time failure
        model.set_state(state)
        raise LinearAlgebraError(f"the linear algebra of the equilibrium search failed: {e}; start nearer an "
                                 "equilibrium, or linearize about 'state'") from None
    except Exception:
        model.set_state(state)
        raise


def _move_to_equilibrium(model, stages: _Stages = _QUIET) -> dict:
    """Move ``model`` to an equilibrium: the rates set to 0 (on a circular orbit: every root turning with the orbit
    frame), then :func:`_rest_search` on each block. Returns how it went (``steps``, the largest ``residual``
    acceleration and its ``scale``).

    Raises
    ------
    LinearAlgebraError
        No equilibrium found: the accelerations where the search stopped are not round-off (the message names the
        largest, where it stopped and, where they do not depend on the positions, that the scene may have none);
        :func:`_to_equilibrium` puts the model back as it was.
    """
    length = _length_scale(model)
    if model.scene.kernel == "body":  # independent bodies, each on its pivot
        for n in ("omega_x", "omega_y", "omega_z"):
            model.set(n, 0.0)
        model.initialize()
        blocks = _blocks(model)
        _check_finite(model, blocks)
        found = [_rest_search(bk, length, stages=stages) for bk in blocks]
        for bk, res in zip(blocks, found):
            _refuse_if_not_rest(bk, res)
        for b, res in enumerate(found):
            for k, n in enumerate(("q_w", "q_x", "q_y", "q_z")):
                model.set(n, float(res.x[k]), body=b)
        model.initialize()
        return _summary(found)
    model.initialize()
    (bk,) = _blocks(model)
    rates = [k for k, n in enumerate(bk.states) if is_rate(n)]
    model._y[:, rates] = 0.0  # every copy at rest (by index: model.set per rate is a search per name)
    model._state_dirty = True
    model._out = None
    orbit = getattr(model.scene, "orbit", None)
    n_orb = 0.0
    if orbit is not None and orbit.circular:
        # on a circular orbit the equilibrium turns with the orbit frame: every root co-rotates at the orbit rate
        # about the orbit normal (world +z), and the search solves f(x) = n xi_world(x) (a relative equilibrium)
        p = model._p if model._p is not None else model._pp
        mu, r = float(p[0, _engine.TP_MU]), float(p[0, _engine.TP_ORBIT_R])
        n_orb = math.sqrt(mu / r**3)
        from ..core.rotations import quat_to_matrix

        for i, b in enumerate(model.scene.tree):
            if b.parent == -1 and b.joint in ("ball", "free_rotation"):
                q = model._y[0, model.layout.coord_slots[(i, "q_w")]:][:4]
                w = quat_to_matrix(q / np.linalg.norm(q)).T @ np.array([0.0, 0.0, n_orb])
                for k, c in enumerate("xyz"):
                    model.set(f"omega_{c}", float(w[k]), body=b.name)
    model.initialize()
    (bk,) = _blocks(model)
    _check_finite(model, [bk])
    res = (_rest_search_closed(bk, length, stages=stages) if bk.closed and not n_orb else
           _rest_search(bk, length, n_orb, stages=stages))
    _refuse_if_not_rest(bk, res)
    x = _wrap_angles(bk, res.x, res.scale)
    y = model._y[0].copy()
    y[:len(x)] = x
    model._y[:] = y
    model._state_dirty = True
    model._out = None
    model.initialize()
    return _summary([res])


def _summary(found: list) -> dict:
    return {"steps": sum(f.steps for f in found), "residual": max(f.residual for f in found),
            "scale": max(f.scale for f in found)}


def _refuse_if_not_rest(bk: _Block, res: _Search) -> None:
    if res.residual <= EQ_RTOL * res.scale:
        return
    nx = len(bk.states)
    coords = [f"{n} = {v + 0.0:.6g}" for n, v in zip(bk.states, res.x[:nx]) if not is_rate(n)]
    where = ", ".join(coords[:6]) + (f", ... ({len(coords)} coordinates)" if len(coords) > 6 else "")
    why = ("the accelerations do not change with the positions there (a constant force, as on a body falling "
           "free or bouncing on a stop: the scene may have no equilibrium)" if res.flat else
           "no step of the positions reduces the accelerations further there (a minimum of them that is not 0)")
    raise LinearAlgebraError(
        f"no equilibrium found from the start state: {why}; a trust-region Newton search stopped after "
        f"{res.steps} steps at {where} with {res.worst}' = {res.value:.6g}, {res.residual / res.scale:.3g} of the "
        f"accelerations' scale {res.scale:.6g} (an equilibrium: at most {EQ_RTOL:g}); start nearer an "
        "equilibrium, or linearize about 'state'")


def linearize(model, *, about=None, system: int = 0, progress=None) -> Linearization:
    """Linearize ``model`` (a :class:`gyrosim.Model`, any scene) about ``about``:

    - ``None`` (default): the present state. Where f(x) = 0 an equilibrium; where the state moves along the
      symmetries (a steady motion) the linearization in the frame that moves with it; else the instantaneous
      Jacobian (``about = "state"`` in the result).
    - ``"state"``: the instantaneous Jacobian, no symmetry taken out.
    - ``"equilibrium"``: the velocities set to 0 and a trust-region Newton search on the accelerations as
      functions of the positions (:func:`_rest_search`) to an equilibrium near the state (the model's state moves
      there, hinge angles wrapped into one turn where the equations do not see the turn); where the search ends
      with accelerations above round-off (EQ_RTOL of their scale) a :class:`LinearAlgebraError` says so.
    - ``"steady"``: the present state must be a steady motion (an error names the residual otherwise).
    - ``"steady_precession"``: a symmetric top on a pivot put in slow steady precession at its theta and spin
      (:func:`steady_precession`), then ``"steady"``.
    - a dict of start values (``{"upper.angle": 0.1}``): set, then as ``None``.

    ``progress(what, done, total)``, where given, is called as the work goes: ``what`` the stage ("equilibrium
    search, Jacobian k", "Jacobian", "eigenvalues"), ``done`` of ``total`` (Jacobian columns; 0 of 1 and 1 of 1 around
    the eigen-decomposition, one long LAPACK call on a large system).

    Returns a :class:`Linearization` (``A, B, C, D, names = linearize(m)``), with the modes and the verdict.

    Examples
    --------
    >>> from gyrosim import Model
    >>> lin = linearize(Model("coupled_pendula"), about="equilibrium")
    >>> [round(m.frequency, 6) for m in lin.oscillations()]   # sqrt(g/L), sqrt(g/L + 2k/(m L^2))
    [3.132092, 3.287856]
    """
    allowed = (None, "state", "equilibrium", "steady", "steady_precession")
    if not isinstance(about, dict) and about not in allowed:
        raise ConfigError("about", about, "state, equilibrium, steady, steady_precession, a dict of start values "
                          "or None")
    stages = _Stages(progress)
    search = _state_from(model, about, stages)
    blocks = _blocks(model, system)
    _check_finite(model, blocks)
    J = _jacobian_of(blocks, stages)
    _check_finite(model, blocks, J.A)
    try:
        return _linearize(model, about, blocks, J, search, stages)
    except np.linalg.LinAlgError as e:
        raise LinearAlgebraError(f"the linear algebra of the linearization failed: {e} (a {J.A.shape[0]}x"
                                 f"{J.A.shape[1]} Jacobian at the state {about or 'as it is'}); the equations are "
                                 "too badly scaled there, or nearly singular") from None


def _linearize(model, about, blocks, J, search=None, stages: _Stages = _QUIET) -> Linearization:
    """:func:`linearize` past the checks: the symmetries taken out, the reduction, the modes and the verdict."""
    Ts, Ps, names, rates, A_rel = [], [], [], {}, []
    kind = "equilibrium"
    at = 0
    for bk in blocks:
        nx = len(bk.states)
        A = J.A[at:at + nx, at:at + nx]
        x = bk.y[0, :nx]
        f = _derivs(bk)
        fs = np.linalg.norm(f)
        if fs <= 1e-12 * np.linalg.norm(A) * max(1.0, np.linalg.norm(x)):
            fs = 0.0  # an equilibrium to round-off
        if search is not None and not bk.orbit:
            fs = 0.0  # the search's: accelerations at most EQ_RTOL of their scale (on an orbit, f = n xi: below)
        Dxi = np.zeros((nx, nx))
        if fs > 0 and about != "state":
            every = _generators(bk, A, bk.y)
            # the world's turn and the cyclic coordinates first; a body's spin only where they do not fit (a
            # sleeping top turns with the world: the same motion, one way to name it)
            for gens in ([g for g in every if not g[0].endswith("spin")], every):
                if gens:
                    G = np.array([g[1] for g in gens]).T
                    c, *_ = np.linalg.lstsq(G, f, rcond=None)
                    res = np.linalg.norm(f - G @ c)
                else:
                    c, res = np.zeros(0), fs
                if res <= STEADY_RTOL * fs:
                    break
            if res <= STEADY_RTOL * fs:
                kind = "steady motion" if kind != "state" else kind
                for (name, _, D), ck in zip(gens, c):
                    if abs(ck) > STEADY_RTOL * max(abs(c).max(), 1e-300):
                        Dxi += ck * D
                        rates[name] = float(ck)
            else:
                if about == "steady" or about == "steady_precession":
                    raise ConfigError("about", about, "a steady motion: the state's derivatives are "
                                      f"{res / fs:.3g} (relative) away from every combination of the symmetries "
                                      f"({', '.join(g[0] for g in every) or 'none'}); set a steady state, or "
                                      "linearize about='state'")
                kind = "state"
        elif fs > 0:
            kind = "state"
        T, P, nm = _reduction(bk, x)
        Ts.append(T)
        Ps.append(P)
        names += nm
        A_rel.append(A - Dxi)
        at += nx
    from scipy.linalg import block_diag

    Ar = block_diag(*A_rel)
    if any(_quats(bk) for bk in blocks):  # else T and P are the identity: no dense products of 1,000 x 1,000
        T = block_diag(*Ts)
        P = block_diag(*Ps)
        Ar, Br, Cr = P @ Ar @ T, P @ J.B, J.C @ T
    else:
        Br, Cr = J.B.copy(), J.C.copy()
    stages.start("eigenvalues", 1)
    if len(blocks) == 1 and blocks[0].closed:
        ev, V = _eig_on_manifold(blocks[0], Ar, _length_scale(model))
    else:
        ev, V = _eig(Ar, names)
    stages.tick()
    modes = modes_of(Ar, names, (ev, V))
    stab = _verdict(Ar, ev)
    state = np.concatenate([bk.y[0, :len(bk.states)] for bk in blocks])
    return Linearization(Ar, Br, Cr, J.D.copy(), Names(names, list(J.inputs), list(J.outputs)), kind, rates,
                         modes, stab, J, state, ev, search)


def _eig_on_manifold(bk: _Block, A: np.ndarray, length: float):
    """The eigenvalues and eigenvectors of a mechanism with loops or gears on their manifold (:func:`_tangent`):
    those of R = L A T, the vectors T w in the named coordinates. A's own spectrum is R's and 2 x rank zeros, the
    directions across the manifold (a projection's kernel, not a symmetry: no mode). Each of R's eigenvalues is
    then replaced by the nearest of A's (within 1e-6 of the spectrum's scale): A comes from the complex step, exact
    to round-off, R carries the finite differences of the tangent space (about 1e-9)."""
    x = bk.y[0, :len(bk.states)]
    T, L = _tangent(bk, x, length)
    if T.shape[1] == 0:
        return np.zeros(0, dtype=complex), np.zeros((A.shape[0], 0), dtype=complex)
    ev_r, W = np.linalg.eig(L @ A @ T)
    ev_a = np.linalg.eigvals(A)
    scale = max(float(np.max(np.abs(ev_a))), 1e-300)
    ev = ev_r.astype(complex)
    for k, lam in enumerate(ev_r):
        j = int(np.argmin(np.abs(ev_a - lam)))
        if abs(ev_a[j] - lam) <= 1e-6 * scale:
            ev[k] = ev_a[j]
    return ev, T @ W


def _verdict(A: np.ndarray, ev=None) -> str:
    if ev is None:
        ev = np.linalg.eigvals(A) if A.size else np.zeros(0)
    scale = max(np.max(np.abs(ev)) if ev.size else 0.0, 1e-300)
    tol = 1e-7 * scale
    if np.any(ev.real > tol):
        return "unstable"
    if ev.size and np.all(ev.real < -tol):
        return "asymptotically stable"
    return "marginally stable"


def _eig(A: np.ndarray, names: list):
    """The eigenvalues and eigenvectors of A. Where A is a second-order system at rest, its rows (coordinates,
    rates) = ([0, I], [G, 0]) (an undamped tree at rest, q' = v, v' = G q: no damping, no gyroscopic term; the
    coordinates and their rates in the same order), from the n x n problem G w = mu w instead of the 2n x 2n one:
    lambda = +-sqrt(mu), the vector (w, lambda w). An eighth of LAPACK's work (a 1,000-state chain: seconds), the
    same numbers to round-off. Else, and below 8 states (as quick either way), LAPACK on A."""
    n2 = A.shape[0]
    rate = np.fromiter((is_rate(s) for s in names), dtype=bool, count=len(names))
    pos, vel = np.flatnonzero(~rate), np.flatnonzero(rate)
    if n2 >= 8 and pos.size * 2 == n2:
        n = pos.size
        tol = 1e-14 * max(float(np.max(np.abs(A))), 1e-300)
        second = (np.all(np.abs(A[np.ix_(pos, pos)]) <= tol) and np.all(np.abs(A[np.ix_(vel, vel)]) <= tol)
                  and np.allclose(A[np.ix_(pos, vel)], np.eye(n), rtol=0, atol=1e-12))
        if second:
            mu, W = np.linalg.eig(A[np.ix_(vel, pos)])
            lam = np.sqrt(mu.astype(complex))
            ev = np.concatenate([lam, -lam])
            V = np.zeros((n2, 2 * n), dtype=complex)
            V[pos, :n], V[vel, :n] = W, W * lam
            V[pos, n:], V[vel, n:] = W, -W * lam
            return ev, V
    return np.linalg.eig(A)


def modes_of(A: np.ndarray, names: list, eig=None) -> list:
    """The eigenvalues of A as :class:`Mode` s (one per complex pair), slowest first (``eig``: A's eigenvalues
    and eigenvectors where known)."""
    if A.size == 0:
        return []
    ev, V = np.linalg.eig(A) if eig is None else eig
    scale = max(np.max(np.abs(ev)), 1e-300)
    out = []
    for k in np.argsort(np.abs(ev), kind="stable"):
        lam = complex(ev[k])
        if lam.imag < -1e-12 * scale:
            continue  # the conjugate of one kept
        if abs(lam.imag) <= 1e-12 * scale:
            lam = complex(lam.real, 0.0)
        v = V[:, k]
        j = int(np.argmax(np.abs(v)))
        v = v / v[j]
        mag = abs(lam)
        zeta = -lam.real / mag if mag > 1e-12 * scale else math.nan
        if mag <= 1e-6 * scale:  # a defective zero pair splits by sqrt(eps)
            kind = "rigid (a symmetry or a conserved quantity)"
        elif abs(lam.imag) > 0:
            kind = "oscillation" if lam.real <= 1e-9 * scale else "growing oscillation"
        else:
            kind = "decaying" if lam.real < 0 else "growing"
        out.append(Mode(lam, abs(lam.imag), mag, zeta, dict(zip(names, v.tolist())), kind))
    return out


# ---------------------------------------------------------------------------------------------------- M, K
def normal_modes(M, K, C=None) -> NormalModes:
    """Normal modes of M x'' + C x' + K x = 0 (M symmetric positive definite, K symmetric).

    Without C: the generalized symmetric eigenproblem K v = w^2 M v; ``frequencies`` w (rad/s, ascending; a
    negative w^2, an unstable direction, gives NaN), ``shapes`` mass-normalised (v^T M v = 1), damping ratios 0.
    With C: the state-space eigenvalues; ``frequencies`` the damped frequencies |Im lambda| of the pairs,
    ``damping_ratios`` -Re lambda / |lambda|, ``shapes`` the displacement parts.

    Examples
    --------
    >>> import numpy as np
    >>> K = np.array([[2., -1, 0], [-1, 2, -1], [0, -1, 2]])   # three masses between two walls, k = m = 1
    >>> np.round(normal_modes(np.eye(3), K).frequencies ** 2, 6)   # 2 - sqrt 2, 2, 2 + sqrt 2
    array([0.585786, 2.      , 3.414214])
    """
    M = np.atleast_2d(np.asarray(M, dtype=float))
    K = np.atleast_2d(np.asarray(K, dtype=float))
    n = M.shape[0]
    for name, X in (("M", M), ("K", K)):
        if X.shape != (n, n) or not np.all(np.isfinite(X)):
            raise ConfigError(name, f"a {X.shape} array", f"a finite ({n}, {n}) matrix")
        if not np.allclose(X, X.T, rtol=1e-12, atol=0):
            raise ConfigError(name, "a matrix that is not symmetric", "a symmetric matrix")
    try:
        Lc = np.linalg.cholesky(M)
    except np.linalg.LinAlgError:
        raise ConfigError("M", "a matrix that is not positive definite", "a positive definite mass matrix") \
            from None
    if C is None:
        Li = np.linalg.inv(Lc)
        w2, U = np.linalg.eigh(Li @ K @ Li.T)
        shapes = Li.T @ U
        w2 = np.where(np.abs(w2) <= 1e-12 * max(np.max(np.abs(w2)), 1e-300), 0.0, w2)  # a rigid mode, to round-off
        with np.errstate(invalid="ignore"):
            w = np.where(w2 >= 0, np.sqrt(np.abs(w2)), np.nan)
        return NormalModes(w, shapes, np.zeros(n), np.sqrt(-w2.astype(complex)))
    C = np.atleast_2d(np.asarray(C, dtype=float))
    if C.shape != (n, n):
        raise ConfigError("C", f"a {C.shape} array", f"a ({n}, {n}) matrix")
    Mi = np.linalg.inv(M)
    A = np.block([[np.zeros((n, n)), np.eye(n)], [-Mi @ K, -Mi @ C]])
    ev, V = np.linalg.eig(A)
    keep = [k for k in range(2 * n) if ev[k].imag >= 0]
    keep.sort(key=lambda k: (abs(ev[k]), ev[k].real))
    keep = keep[:n]
    lam = ev[keep]
    mag = np.abs(lam)
    with np.errstate(invalid="ignore", divide="ignore"):
        zeta = np.where(mag > 0, -lam.real / mag, np.nan)
    return NormalModes(np.abs(lam.imag), V[:n, keep], zeta, lam)
