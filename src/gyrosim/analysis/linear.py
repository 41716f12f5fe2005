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

    def dominant(self, k: int = 3) -> list:
        """The ``k`` state names with the largest components, coordinates (angles, small rotations, positions)
        before rates."""
        rates = ("rate", "omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z")
        disp = [n for n in self.shape if not n.rpartition(".")[2].startswith(rates)]
        pick = sorted(disp, key=lambda n: -abs(self.shape[n]))
        pick = [n for n in pick if abs(self.shape[n]) > 1e-9 * abs(self.shape[pick[0]])] if pick else []
        rest = sorted((n for n in self.shape if n not in disp), key=lambda n: -abs(self.shape[n]))
        return (pick + rest)[:k]

    def displacement_shape(self) -> dict:
        """The shape's coordinates (not its rates), the largest 1 and the others in phase with it (real for an
        undamped mode)."""
        d = {n: v for n, v in self.shape.items() if n in self.dominant(len(self.shape))
             and not n.rpartition(".")[2].startswith(("rate", "omega_", "v_"))}
        if not d:
            return {}
        big = max(d.values(), key=abs)
        return {n: v / big for n, v in d.items() if abs(v) > 1e-9 * abs(big)}


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
        return np.linalg.eigvals(self.A)

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
                       outputs, roots, hinges, float(model._p[system, _engine.TP_G]) != 0.0, orbit)]
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


def _column(bk: _Block, vy: np.ndarray, vp: np.ndarray):
    """One column of the Jacobian as the model-exchange FMUs compute it (``gs_directional`` in the FMU glue), to
    the bit: the quaternion rates dq/dt = q (0, omega)/2 and the coordinates as outputs at q as it is, with the
    seed as given; every other row at q normalised, a quaternion's seed projected on the unit sphere's tangent
    ((e_k - q^ q^_k) / |q|): what the engine integrates, whose dynamics see only the rotation q stands for."""
    nx = len(bk.states)
    nout = _engine.tree_info(bk.desc)[3]
    raw_d, raw_o = np.zeros(nx + 1), np.zeros(nout)
    _engine.tree_directional(bk.desc, bk.y, bk.p, vy, vp, raw_d, raw_o)
    y, vn = bk.y.copy(), vy.copy()
    for k in _quats(bk):
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
    for k in _quats(bk):
        inq[k:k + 4] = True
    d = np.where(inq, raw_d[:nx], n_d[:nx])
    o = np.array([raw_o[i] if i < nx else n_o[i] for _, i in bk.outputs])
    return d, o


def _block_jacobian(bk: _Block):
    nx = len(bk.states)
    A = np.zeros((nx, nx))
    C = np.zeros((len(bk.outputs), nx))
    B = np.zeros((nx, len(bk.inputs)))
    D = np.zeros((len(bk.outputs), len(bk.inputs)))
    zp = np.zeros(bk.p.shape[0])
    for j in range(nx):
        vy = np.zeros(nx)
        vy[j] = 1.0
        A[:, j], C[:, j] = _column(bk, vy, zp)
    for j, (_, cols) in enumerate(bk.inputs):
        vp = np.zeros_like(zp)
        for col, f in cols:
            vp[col] = f
        B[:, j], D[:, j] = _column(bk, np.zeros(nx), vp)
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


def _jacobian_of(blocks: list) -> Jacobian:
    parts = [(_block_jacobian(bk), bk) for bk in blocks]
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


def _generators(bk: _Block, A: np.ndarray, y: np.ndarray) -> list:
    """The symmetries of this tree at this state: [(name, xi(x0) (nx,), D xi (nx, nx))]."""
    nx = len(bk.states)
    x = y[0, :nx]
    gens = []
    if bk.roots:
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
        for k, s in enumerate(bk.states):  # an orbit's anomaly turns with the world
            if s.endswith("anomaly") and bk.orbit:
                Dw[k, :] = 0.0
        xi = Dw @ x
        for k, s in enumerate(bk.states):
            if s.endswith("anomaly") and bk.orbit:
                xi[k] = 1.0
        gens.append(("world", xi, Dw))
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


def _state_from(model, about) -> None:
    if isinstance(about, dict):
        for k, v in about.items():
            model.set(k, v)
        model.initialize()
    elif about == "steady_precession":
        steady_precession(model)
    elif about == "equilibrium":
        _to_equilibrium(model)


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


def _to_equilibrium(model, tol: float = 1e-13, iters: int = 50) -> None:
    """Newton on f(x) = 0 from the present state, velocities set to 0 first (a tree or a one-body model)."""
    if model.scene.kernel == "body":  # independent bodies: at rest where they are
        for n in ("omega_x", "omega_y", "omega_z"):
            model.set(n, 0.0)
        model.initialize()
        return
    for n, v in model.variables.items():
        if v.causality == "output" and v.start is not None and n.rpartition(".")[2] in (
                "rate", "omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z"):
            model.set(n, 0.0)
    orbit = getattr(model.scene, "orbit", None)
    n_orb = 0.0
    if orbit is not None and orbit.circular:
        # on a circular orbit the equilibrium turns with the orbit frame: every root co-rotates at the orbit rate
        # about the orbit normal (world +z), and Newton solves f(x) = n xi_world(x) (a relative equilibrium)
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
    _check_finite(model, _blocks(model))
    for _ in range(iters):
        (bk,) = _blocks(model)
        x = bk.y[0, :len(bk.states)]
        A, *_ = _block_jacobian(bk)
        f = _derivs(bk)
        if n_orb:
            (_, xi, Dw), *_ = _generators(bk, A, bk.y)
            f = f - n_orb * xi
            A = A - n_orb * Dw
        T, P, _ = _reduction(bk, x)
        if not (np.all(np.isfinite(A)) and np.all(np.isfinite(f))):
            _check_finite(model, [bk], A)
        try:
            dz = np.linalg.lstsq(A @ T, -f, rcond=None)[0]
        except np.linalg.LinAlgError as e:
            raise LinearAlgebraError(f"Newton's step toward the equilibrium failed: {e} (a {A.shape[0]}x"
                                     f"{A.shape[1]} Jacobian); linearize about='state' instead") from None
        dx = T @ dz
        y = model._y[0].copy()
        y[:len(bk.states)] += dx
        model._y[:] = y
        model._state_dirty = True
        model._out = None
        model.initialize()
        if np.linalg.norm(dz) <= tol * max(1.0, np.linalg.norm(x)):
            return
    raise ConfigError("about", "equilibrium", f"a state from which Newton's method finds one; {iters} iterations "
                      "did not converge (start nearer to it, or linearize about='state')")


def linearize(model, *, about=None, system: int = 0) -> Linearization:
    """Linearize ``model`` (a :class:`gyrosim.Model`, any scene) about ``about``:

    - ``None`` (default): the present state. Where f(x) = 0 an equilibrium; where the state moves along the
      symmetries (a steady motion) the linearization in the frame that moves with it; else the instantaneous
      Jacobian (``about = "state"`` in the result).
    - ``"state"``: the instantaneous Jacobian, no symmetry taken out.
    - ``"equilibrium"``: the velocities set to 0 and Newton's method to the nearest equilibrium (the model's state
      moves there).
    - ``"steady"``: the present state must be a steady motion (an error names the residual otherwise).
    - ``"steady_precession"``: a symmetric top on a pivot put in slow steady precession at its theta and spin
      (:func:`steady_precession`), then ``"steady"``.
    - a dict of start values (``{"upper.angle": 0.1}``): set, then as ``None``.

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
    _state_from(model, about)
    blocks = _blocks(model, system)
    _check_finite(model, blocks)
    J = _jacobian_of(blocks)
    _check_finite(model, blocks, J.A)
    try:
        return _linearize(model, about, blocks, J)
    except np.linalg.LinAlgError as e:
        raise LinearAlgebraError(f"the linear algebra of the linearization failed: {e} (a {J.A.shape[0]}x"
                                 f"{J.A.shape[1]} Jacobian at the state {about or 'as it is'}); the equations are "
                                 "too badly scaled there, or nearly singular") from None


def _linearize(model, about, blocks, J) -> Linearization:
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

    T = block_diag(*Ts)
    P = block_diag(*Ps)
    Ar = P @ block_diag(*A_rel) @ T
    Br = P @ J.B
    Cr = J.C @ T
    modes = modes_of(Ar, names)
    stab = _verdict(Ar)
    state = np.concatenate([bk.y[0, :len(bk.states)] for bk in blocks])
    return Linearization(Ar, Br, Cr, J.D.copy(), Names(names, list(J.inputs), list(J.outputs)), kind, rates,
                         modes, stab, J, state)


def _verdict(A: np.ndarray) -> str:
    ev = np.linalg.eigvals(A) if A.size else np.zeros(0)
    scale = max(np.max(np.abs(ev)) if ev.size else 0.0, 1e-300)
    tol = 1e-7 * scale
    if np.any(ev.real > tol):
        return "unstable"
    if ev.size and np.all(ev.real < -tol):
        return "asymptotically stable"
    return "marginally stable"


def modes_of(A: np.ndarray, names: list) -> list:
    """The eigenvalues of A as :class:`Mode` s (one per complex pair), slowest first."""
    if A.size == 0:
        return []
    ev, V = np.linalg.eig(A)
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
        out.append(Mode(lam, abs(lam.imag), mag, zeta, {n: complex(x) for n, x in zip(names, v)}, kind))
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
