"""The Hamiltonian view of any scene: canonical momenta, the Hamiltonian, and how symplectic each integrator's
one-step map is.

(The module is ``hamilton``, not ``hamiltonian``: a submodule of that name would shadow the function
``gyrosim.analysis.hamiltonian`` once imported.)

Coordinates and momenta. A scene's configuration is its joints' coordinates: a hinge's ``angle`` (rad), a ``free``
body's position ``r_x..z`` (m, world) and, for every ``ball``, ``free_rotation`` or ``free`` joint (and a one-body
scene's body), its rotation, charted by the rotation vector ``rot_x..z`` (rad) in the body (child) frame about a base
attitude q0: ``q = q0 exp(rot / 2)``, the chart :func:`gyrosim.analysis.linear.linearize` names ``<body>.rot_x..z``.
The kinetic energy T is quadratic in the velocities (``rate``, ``v_x..z``, ``omega_x..z``: body frame, relative to
the parent, DESIGN section 4b), so the momenta conjugate to the coordinates are

- ``<body>.p_angle`` = dT/d(rate) (kg*m^2/s): the angular momentum of the body and everything below it about the
  hinge's axis, through the joint point;
- ``<body>.p_r_x..z`` = dT/d(v_x..z) (kg*m/s, world): the linear momentum of the body and everything below it;
- ``<body>.p_rot_x..z`` = dT/d(omega_x..z) (kg*m^2/s, body frame): the body-frame momentum map, the angular
  momentum of the body and everything below it about its joint point (a one-body scene: about the pivot, I omega),
  in the body's axes. It is the momentum conjugate to ``rot`` at ``rot = 0`` (the base attitude itself); away from
  it ``p_rot = J_r(rot)^T dT/domega`` with J_r the right Jacobian of the rotation vector (omega = J_r(rot) rot').

The hinge angles and positions come first, then the rotations, each followed in p by its momenta in the same
order. A one-body scene of one body, and a tree of one body, use the bare names (``p_rot_x``), as every variable.

Exact momenta. dT/dv_j is the derivative of the engine's ``energy`` output along the velocity coordinate v_j, by
the engine's complex step (``gs_tree_directional``, as :func:`gyrosim.analysis.linear.jacobian` gets its columns):
exact to round-off, no difference quotient (the potential does not depend on the velocities). The mass matrix
M(q), column j = dT/dv at v = e_j, comes the same way, exactly, since T = v^T M(q) v / 2.

The Hamiltonian H(q, p) = T + V, the engine's ``energy`` at the state with v = M(q)^-1 p: the conserved energy
where the scene is conservative (no joint damping, inputs at 0; gravity, joint springs and couplings are in V).
On a circular orbit the gravity gradient and the tidal forces act through a potential that turns with the orbit
(a Hamiltonian that depends on time) and is not in ``energy``: :func:`hamiltonian` refuses such a scene.

Symplecticity. :func:`symplecticity_error` measures how far an integrator's one-step map Phi_h (one internal step:
``max_step = h``) is from preserving the symplectic form: M^T J M - J, M = dPhi_h/dx in the canonical coordinates
x = (q, p) above, J = [[0, I], [-I, 0]]. A symplectic method (the splittings and exact-flow splittings of the
one-body kernel, its exact flow) gives zero to the measurement's floor (a map that is not a smooth function of
the state shows a floor above :data:`NOT_SMOOTH`); a Runge-Kutta method
does not (rk4: the defect is O(h^5) per step; euler: O(h^2)). Damping makes the exact flow itself contract phase
space: the measured defect of a damped scene then is the flow's, not only the integrator's (``conservative`` in the
result says so).

Examples
--------
>>> from gyrosim import Model
>>> m = Model("heavy_top")
>>> p = canonical_momenta(m)
>>> sorted(p)
['p_rot_x', 'p_rot_y', 'p_rot_z']
>>> round(p["p_rot_z"], 12)   # I3 omega_z = 1e-3 kg*m^2 * 60 rad/s
0.06
>>> hamiltonian(m) == m.get("energy")
True
>>> r = symplecticity_error("heavy_top", "strang_exact", 0.01)
>>> r.error < 1e-9   # symplectic: at the floor
True
>>> symplecticity_error("heavy_top", "rk4", 0.01).error > 1e-8
True
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.tree import ORBIT_COORD
from ..errors import ConfigError

__all__ = ["CanonicalChart", "Symplecticity", "canonical_momenta", "hamiltonian", "mass_matrix",
           "symplecticity_error", "symplecticity_errors"]

#: The velocity paired with each configuration coordinate (a quaternion's: its three omegas).
_PARTNER = {"angle": "rate", "r_x": "v_x", "r_y": "v_y", "r_z": "v_z", "displacement": "velocity"}
#: The relative size of the difference steps of the Jacobian (scaled coordinates: rad, and momenta over S).
EPS = 1e-3
#: A floor above this is no measurement: the map is not a smooth function of the state at the difference steps.
NOT_SMOOTH = 1e-6


# ---------------------------------------------------------------------------------------------------- rotations
def _qmul(a, b):
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz, aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx, aw * bz + ax * by - ay * bx + az * bw])


def _qexp(rot):
    """The unit quaternion of the rotation vector ``rot`` (3,), rad."""
    a = math.sqrt(float(rot @ rot))
    s = 0.5 - a * a / 48.0 if a < 1e-4 else math.sin(0.5 * a) / a
    return np.array([math.cos(0.5 * a), *(s * rot)])


def _qlog(q):
    """The rotation vector (rad, |rot| <= pi) of the unit quaternion ``q``."""
    q = q if q[0] >= 0 else -q
    v = q[1:]
    n = math.sqrt(float(v @ v))
    ang = 2.0 * math.atan2(n, q[0])
    return v * (ang / n) if n > 0 else 2.0 * v


def _hat(a):
    x, y, z = a
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def right_jacobian(rot) -> np.ndarray:
    """J_r(rot) (3, 3): omega = J_r(rot) rot' for R = R0 Exp(rot) (omega in the body frame)."""
    rot = np.asarray(rot, dtype=float)
    t2 = float(rot @ rot)
    if t2 < 1e-4:
        a = 0.5 - t2 / 24.0 + t2 * t2 / 720.0          # (1 - cos t) / t^2
        b = 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0   # (t - sin t) / t^3
    else:
        t = math.sqrt(t2)
        a = (1.0 - math.cos(t)) / t2
        b = (t - math.sin(t)) / (t2 * t)
    K = _hat(rot)
    return np.eye(3) - a * K + b * (K @ K)


# ---------------------------------------------------------------------------------------------------- the chart
class CanonicalChart:
    """Canonical coordinates x = (q, p) of one system of a model, and the maps between them and the model's state.

    Parameters
    ----------
    model : Model
        Any scene; its present state is the chart's base (the quaternions' base attitudes).
    system : int
        The system (a body of a one-body scene, a copy of a tree).

    Attributes
    ----------
    names : list of str
        2n names: the coordinates (``<body>.angle``, ``<body>.r_x``, ``<body>.rot_x``) then their momenta
        (``<body>.p_angle``, ``<body>.p_r_x``, ``<body>.p_rot_x``).
    x0 : (2n,) ndarray
        The present state in these coordinates (rotations 0: the base).
    kinds : list of str
        Per coordinate: ``angle`` (rad), ``length`` (m) or ``rotation`` (rad).

    Notes
    -----
    A circular orbit's ``orbit_anomaly`` is the clock of the orbit's turning potential, not a degree of freedom: it
    keeps its value in :meth:`to_state` and is not among the coordinates.
    """

    def __init__(self, model, system: int = 0):
        from .linear import _blocks

        self.model = model
        self.system = system
        model.initialize()
        bk = _blocks(model, system)[0] if model.scene.kernel == "tree" else _blocks(model)[system]
        self._bk = bk
        self._nx = len(bk.states)
        self._e = next(i for i, (n, _) in enumerate(bk.outputs) if n.rpartition(".")[2] == "energy")
        coords = model.coordinates
        slot_of = {v: s for v, _, s in coords}
        self.ncoord = model.n_coords
        pre = ""
        if model.scene.kernel == "body" and model.n_bodies > 1:
            pre = f"{model.body_names[system]}."
        self._lin, self._quat = [], []  # slots of the linear coordinates and of the quaternions
        vl, vq, ql, pl, kl, qq, pq = [], [], [], [], [], [], []  # linear ones first, then the rotations
        for var, c, slot in coords:
            base, _, _ = var.rpartition(".")
            head = f"{pre}{base}." if base else pre
            if c == ORBIT_COORD or c in ("q_x", "q_y", "q_z") or c in _PARTNER.values() \
                    or c.startswith(("omega_", "v_")):
                continue
            if c == "q_w":
                w = var[:-len("q_w")] + "omega_x"
                if w not in slot_of:
                    raise ConfigError("scene", model.scene.name, f"a rotation with its rates ({var} has no {w})")
                self._quat.append(slot)
                vq += [slot_of[w], slot_of[w] + 1, slot_of[w] + 2]
                qq += [f"{head}rot_{a}" for a in "xyz"]
                pq += [f"{head}p_rot_{a}" for a in "xyz"]
            elif c in _PARTNER:
                v = var[:-len(c)] + _PARTNER[c]
                if v not in slot_of:
                    raise ConfigError("scene", model.scene.name, f"a coordinate with its rate ({var} has no {v})")
                self._lin.append(slot)
                vl.append(slot_of[v])
                ql.append(f"{pre}{var}")
                pl.append(f"{head}p_{c}")
                kl.append("length" if c.startswith("r_") or c == "displacement" else "angle")
            else:
                raise ConfigError("scene", model.scene.name, f"coordinates the Hamiltonian view knows ({var}: "
                                  f"{c!r} has no conjugate velocity here)")
        self._vel = vl + vq  # the velocities in the order of the pairs
        self.n = len(self._vel)
        if self.n == 0:
            raise ConfigError("scene", model.scene.name, "a scene with a moving joint (this one has no coordinates)")
        self.names = ql + qq + pl + pq
        self.kinds = kl + ["rotation"] * len(qq)
        self.base = model._y[system, :self.ncoord].copy()
        self.x0 = self.from_state(self.base)

    # ---------------------------------------------------------------------------------- exact derivatives of E
    def _directional(self, coords: np.ndarray, seeds) -> np.ndarray:
        """dE/dv along each velocity slot of ``seeds`` at the state ``coords`` (ncoord,): the engine's complex step
        (``gs_tree_directional``; the quaternions of ``coords`` are unit, so no projection is needed)."""
        from ..core import _engine

        y = self._bk.y.copy()
        y[0, :self._nx] = coords[:self._nx]
        for s in self._quat:
            y[0, s:s + 4] /= np.linalg.norm(y[0, s:s + 4])
        vp = np.zeros(self._bk.p.shape[0])
        d, o = np.zeros(self._nx + 1), np.zeros(_engine.tree_info(self._bk.desc)[3])
        e = self._bk.outputs[self._e][1]
        out = np.empty(len(seeds))
        for j, s in enumerate(seeds):
            vy = np.zeros(self._nx)
            vy[s] = 1.0
            _engine.tree_directional(self._bk.desc, y, self._bk.p, vy, vp, d, o)
            out[j] = o[e]
        return out

    def _grad_v(self, coords: np.ndarray) -> np.ndarray:
        """dE/dv (n,) at the state ``coords`` (ncoord,), the velocities in pair order: exact to round-off."""
        return self._directional(coords, self._vel)

    def mass_matrix(self, coords: np.ndarray | None = None) -> np.ndarray:
        """M(q) (n, n) at the configuration of ``coords`` (default: the base state), velocities in pair order:
        T = v^T M v / 2, M_ij = dE/dv_i at v = e_j (exact; the upper triangle computed, M symmetric)."""
        c = (self.base if coords is None else np.asarray(coords, dtype=float)).copy()
        c[self._vel] = 0.0
        M = np.empty((self.n, self.n))
        for j, s in enumerate(self._vel):
            c[s] = 1.0
            M[:j + 1, j] = self._directional(c, self._vel[:j + 1])
            M[j, :j] = M[:j, j]
            c[s] = 0.0
        return M

    # ---------------------------------------------------------------------------------- the maps
    def from_state(self, coords: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
        """x = (q, p) (2n,) of the state ``coords`` (ncoord,); rotations charted about the attitudes of ``base``
        (a state, default the chart's base)."""
        coords = np.asarray(coords, dtype=float)
        base = self.base if base is None else base
        q = [coords[s] for s in self._lin]
        pv = self._grad_v(coords)
        p = list(pv[:len(self._lin)])
        k = len(self._lin)
        for j, s in enumerate(self._quat):
            q0 = base[s:s + 4] / np.linalg.norm(base[s:s + 4])
            qq = coords[s:s + 4] / np.linalg.norm(coords[s:s + 4])
            rot = _qlog(_qmul(q0 * np.array([1.0, -1.0, -1.0, -1.0]), qq))
            q += list(rot)
            p += list(right_jacobian(rot).T @ pv[k + 3 * j:k + 3 * j + 3])
        return np.array(q + p)

    def to_state(self, x: np.ndarray, base: np.ndarray | None = None) -> np.ndarray:
        """The state coordinates (ncoord,) of x = (q, p) (2n,), rotations about the attitudes of ``base``; the
        velocities v = M(q)^-1 p."""
        x = np.asarray(x, dtype=float)
        base = self.base if base is None else base
        n, k = self.n, len(self._lin)
        c = base.copy()
        pv = np.array(x[n:n + k].tolist() + [0.0] * (n - k))
        for i, s in enumerate(self._lin):
            c[s] = x[i]
        for j, s in enumerate(self._quat):
            rot = x[k + 3 * j:k + 3 * j + 3]
            q0 = base[s:s + 4] / np.linalg.norm(base[s:s + 4])
            c[s:s + 4] = _qmul(q0, _qexp(rot))
            pv[k + 3 * j:k + 3 * j + 3] = np.linalg.solve(right_jacobian(rot).T, x[n + k + 3 * j:n + k + 3 * j + 3])
        c[self._vel] = np.linalg.solve(self.mass_matrix(c), pv)
        return c

    def energy(self, coords: np.ndarray) -> float:
        """The engine's ``energy`` output (J) at the state ``coords``."""
        from ..core import _engine

        y = self._bk.y.copy()
        y[0, :self._nx] = coords[:self._nx]
        out = np.zeros(_engine.tree_info(self._bk.desc)[3])
        _engine.tree_outputs(self._bk.desc, y, self._bk.p.reshape(1, -1), out)
        return float(out[self._bk.outputs[self._e][1]])

    def hamiltonian(self, x: np.ndarray) -> float:
        """H(q, p) (J): the energy at the state of x (see the module's notes for where it is the Hamiltonian)."""
        return self.energy(self.to_state(x))


# ---------------------------------------------------------------------------------------------------- public API
def _refuse_orbit(model, what: str) -> None:
    orbit = getattr(model.scene, "orbit", None)
    if orbit is not None and orbit.circular:
        raise ConfigError("scene", model.scene.name, f"a scene whose energy output is its Hamiltonian for {what}; on "
                          "a circular orbit the gravity gradient and the tidal forces act through a potential that "
                          "turns with the orbit (a Hamiltonian that depends on time) and is not in 'energy'")


def canonical_momenta(model, *, system: int = 0) -> dict[str, float]:
    """The momenta conjugate to the scene's coordinates at the model's present state, by name.

    ``<body>.p_angle`` (kg*m^2/s) per hinge, ``<body>.p_rot_x..z`` (kg*m^2/s, body frame: dT/domega, the momentum
    conjugate to the rotation vector at the present attitude) per rotating joint, ``<body>.p_r_x..z`` (kg*m/s,
    world) per ``free`` joint; bare names in a scene of one body. Each is dT/dv of the engine's energy by the
    complex step: exact to round-off.

    Parameters
    ----------
    model : Model
    system : int
        The body of a one-body scene, or the copy of a tree.

    Returns
    -------
    dict
        name -> float.

    Examples
    --------
    >>> from gyrosim import Model
    >>> p = canonical_momenta(Model("double_pendulum", parameters={"upper.rate": 1.0}))
    >>> sorted(p)
    ['lower.p_angle', 'upper.p_angle']
    """
    ch = CanonicalChart(model, system)
    return {nm: float(v) for nm, v in zip(ch.names[ch.n:], ch.x0[ch.n:])}


def mass_matrix(model, *, system: int = 0) -> tuple[np.ndarray, list]:
    """The mass matrix M(q) (n, n) at the model's present configuration (T = v^T M v / 2, exact) and the names of
    the velocities in its order (``<body>.rate``, ``<body>.omega_x``, ...)."""
    ch = CanonicalChart(model, system)
    vnames = {s: v for v, _, s in model.coordinates}
    return ch.mass_matrix(), [vnames[s] for s in ch._vel]


def hamiltonian(model, *, system: int = 0) -> float:
    """H = T + V (J) at the model's present state: the engine's ``energy``, which is the Hamiltonian of the
    scene's canonical coordinates (kinetic energy, gravity, joint springs and couplings). It is conserved where the
    scene is conservative: no joint damping and the inputs (motor torques, external torques) at 0.

    Raises
    ------
    ConfigError
        A scene on a circular orbit (its potential turns with the orbit and is not in ``energy``).
    """
    _refuse_orbit(model, "hamiltonian()")
    model.initialize()
    if model.scene.kernel == "tree":
        return float(model._outputs_array()[system, model.scene.output_names().index("energy")])
    return float(model.get("energy", body=system))


def _dissipation(model, system: int) -> list[str]:
    """The variables that make the scene not conservative now: damping > 0, inputs != 0."""
    out = []
    for n, v in model.variables.items():
        short = n.rpartition(".")[2]
        if (v.causality == "parameter" and short in ("damping", "joint_damping")) or v.causality == "input":
            try:
                x = model.get(n, system=system) if model.scene.kernel == "tree" else model.get(n, body=system)
            except (ConfigError, TypeError):
                continue
            if x != 0.0:
                out.append(f"{n} = {x:g}")
    return out


@dataclass
class Symplecticity:
    """The symplecticity error of one integrator's one-step map (:func:`symplecticity_error`).

    Attributes
    ----------
    scene, integrator : str
    h : float
        s, one internal step (``max_step = h``).
    error : float
        max |M~^T J M~ - J| over the entries, in the scaled coordinates (q in rad or m, p / S): dimensionless.
    frobenius : float
        The Frobenius norm of the same matrix.
    floor : float
        The measurement's floor: the difference of the defect between the Jacobian with steps eps and 2 eps, over
        15 (the fourth-order difference's truncation error), plus the round-off of the quotients.
    scale : float
        S (kg*m^2/s or kg*m/s per rad or m): the momenta's scale, S = sqrt(|dp'/dq| / |dq'/dp|), which makes the
        two off-diagonal blocks of one size (so the error does not depend on the units).
    M : (2n, 2n) ndarray
        dPhi/dx in the unscaled canonical coordinates (``names``).
    names : list of str
    conservative : bool
        False where damping or a non-zero input acts: the exact flow itself is then not symplectic.
    note : str
    """

    scene: str
    integrator: str
    h: float
    error: float
    frobenius: float
    floor: float
    scale: float
    M: np.ndarray = field(repr=False)
    names: list = field(repr=False)
    conservative: bool = True
    note: str = ""

    @property
    def smooth(self) -> bool:
        """Whether the measurement means anything: a floor at most :data:`NOT_SMOOTH` (a larger one says the map
        is not a smooth function of the state at the difference steps)."""
        return self.floor <= NOT_SMOOTH

    @property
    def at_floor(self) -> bool:
        """Whether the error is within the measurement's floor (a symplectic map, as far as it can tell), the floor
        being a measurement (:attr:`smooth`)."""
        return self.smooth and self.error <= self.floor

    def record(self) -> dict:
        """A flat dict for tables (the study)."""
        return {"scene": self.scene, "integrator": self.integrator, "h": self.h, "error": self.error,
                "floor": self.floor, "frobenius": self.frobenius, "conservative": self.conservative,
                "smooth": self.smooth}


def _prepare(scene, about):
    from ..model import Model
    from .chaos import _copies

    if isinstance(scene, Model):
        model = _copies(scene, 1)
    else:
        model = Model(scene)
    if isinstance(about, dict):
        for k, v in about.items():
            model.set(k, v)
    elif about is not None:
        raise ConfigError("about", about, "None (the scene's or the model's present state) or a dict of start "
                          "values")
    model.initialize()
    return model


def _jacobians(model, ch: CanonicalChart, integrator: str, h: float, steps: np.ndarray, system: int):
    """Phi_h's images of x0 and of x0 +- {1, 2, 4} steps_i e_i, in one engine call of copies; then the fourth-order
    central differences with steps and with twice them: (M_a, M_b, the images in x)."""
    from .chaos import _copies

    n2 = 2 * ch.n
    shifts = [0.0]
    for i in range(n2):
        for f in (1.0, -1.0, 2.0, -2.0, 4.0, -4.0):
            shifts.append((i, f))
    r = len(shifts)
    cm = _copies(model, r)
    cm.set("integrator", integrator)
    cm.set("max_step", h)
    cm.set("max_drift", 0.0)
    k = model.n_systems
    rows = np.arange(r) * k + system
    coords = np.empty((r, ch.ncoord))
    for j, sft in enumerate(shifts):
        x = ch.x0.copy()
        if sft != 0.0:
            i, f = sft
            x[i] += f * steps[i]
        coords[j] = ch.to_state(x)
    bad = cm._restart_rows(rows, coords)
    if bad >= 0:
        raise ConfigError("h", h, f"a step from states near the start (one is not finite: {coords[bad].tolist()})")
    cm.step(h)
    after = cm._y[rows, :ch.ncoord]
    base1 = after[0].copy()
    X = np.array([ch.from_state(after[j], base=base1) for j in range(r)])
    F = {sft: X[j] for j, sft in enumerate(shifts)}
    Ma, Mb = np.empty((n2, n2)), np.empty((n2, n2))
    for i in range(n2):
        d = {f: F[(i, f)] for f in (1.0, -1.0, 2.0, -2.0, 4.0, -4.0)}
        d1 = (d[1.0] - d[-1.0]) / (2 * steps[i])
        d2 = (d[2.0] - d[-2.0]) / (4 * steps[i])
        d4 = (d[4.0] - d[-4.0]) / (8 * steps[i])
        Ma[:, i] = (4 * d1 - d2) / 3
        Mb[:, i] = (4 * d2 - d4) / 3
    return Ma, Mb, X


def _defect(M: np.ndarray, n: int, S: float) -> np.ndarray:
    D = np.concatenate([np.ones(n), np.full(n, S)])
    Ms = M * D[None, :] / D[:, None]  # D^-1 M D: q as they are, p / S
    J = np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])
    return Ms.T @ J @ Ms - J


def _balance(M: np.ndarray, n: int, fallback: float) -> float:
    B = np.linalg.norm(M[:n, n:])
    C = np.linalg.norm(M[n:, :n])
    return math.sqrt(C / B) if B > 0 and C > 0 and math.isfinite(C / B) else fallback


def symplecticity_error(scene, integrator: str, h: float, *, about=None, system: int = 0) -> Symplecticity:
    """How far one step of ``integrator`` is from a symplectic map: max |M^T J M - J|, M = dPhi_h/dx.

    Phi_h is one internal step of ``h`` s (``max_step = h``; ``adaptive`` and ``dop853`` take their own steps in
    it) from the start state, in the canonical coordinates x = (q, p) of :class:`CanonicalChart` (hinge angles,
    positions and rotation vectors about the attitudes before and after the step, with their conjugate momenta).
    M comes from fourth-order central differences of the engine's step (all the neighbours in one engine call) with
    steps EPS = 1e-3 in q (rad, m) and EPS * S in p; their truncation error is O(EPS^4) and is measured (``floor``:
    the change from steps EPS to 2 EPS, over 15) with the round-off of the quotients, about 1e-13 / EPS of the
    state's size. The error is the largest entry of M~^T J M~ - J in coordinates scaled to be dimensionless (q; p /
    S, S balancing the blocks dq'/dp and dp'/dq), J = [[0, I], [-I, 0]].

    Parameters
    ----------
    scene : str, Path, Scene or Model
        A Model is copied at its present state (not advanced).
    integrator : str
        One of ``Scene.integrators`` of the scene.
    h : float
        s.
    about : dict, optional
        Start values to set first (``{"upper.angle": 0.5}``).
    system : int

    Returns
    -------
    Symplecticity

    Raises
    ------
    ConfigError
        An integrator the scene does not take (or ``exact`` where it does not apply), h not > 0, a scene without
        coordinates.

    Examples
    --------
    >>> r = symplecticity_error("double_pendulum", "rk4", 0.01)
    >>> 1e-12 < r.error < 1e-6   # rk4 is not symplectic: an O(h^5) defect per step
    True
    """
    try:
        h = float(h)
    except (TypeError, ValueError):
        h = math.nan
    if not (math.isfinite(h) and h > 0):
        raise ConfigError("h", h, "a finite step > 0 in s")
    model = _prepare(scene, about)
    model.set("integrator", integrator)
    ch = CanonicalChart(model, system)
    n = ch.n
    Mm = ch.mass_matrix()
    rate = model.fastest_rate(system)
    S = float(np.max(np.abs(np.diag(Mm)))) * max(1.0, rate if math.isfinite(rate) else 1.0)
    S = S if S > 0 else 1.0
    for _ in range(3):  # the scale from the Jacobian itself (its blocks balanced); again if it moved much
        steps = EPS * np.concatenate([np.ones(n), np.full(n, S)])
        Ma, Mb, X = _jacobians(model, ch, integrator, h, steps, system)
        S_new = _balance(Ma, n, S)
        if 0.1 <= S_new / S <= 10.0:
            S = S_new
            break
        S = S_new
    Da = _defect(Ma, n, S)
    Db = _defect(Mb, n, S)
    D = np.concatenate([np.ones(n), np.full(n, S)])
    m_scaled = float(np.max(np.abs(Ma * D[None, :] / D[:, None])))
    # truncation: a fourth-order quotient's error is (its change from EPS to 2 EPS) / 15; round-off: eps |x'| / step
    # in each entry of M~, times the 2n terms of a product
    x_scaled = max(1.0, float(np.max(np.abs(X / D))))
    floor = float(np.max(np.abs(Da - Db))) / 15.0 + 2 * n * m_scaled * 2.2e-16 * x_scaled / EPS
    diss = _dissipation(model, system)
    note = ("not conservative (" + ", ".join(diss) + "): the exact flow is not symplectic either") if diss else ""
    return Symplecticity(model.scene.name, integrator, h, float(np.max(np.abs(Da))), float(np.linalg.norm(Da)),
                         floor, S, Ma, ch.names, not diss, note)


def symplecticity_errors(scene, h, *, integrators=None, about=None, system: int = 0) -> list[Symplecticity]:
    """:func:`symplecticity_error` for every integrator the scene takes (``Scene.integrators``, so new methods
    appear by themselves) or those given, at each step of ``h`` (a float or a sequence). An integrator that does not
    apply to the scene's state (``exact`` on a body that is not a Lagrange top) is left out."""
    from ..model import Model
    from ..scene import load_scene

    sc = scene.scene if isinstance(scene, Model) else load_scene(scene)
    hs = [h] if np.ndim(h) == 0 else list(h)
    out = []
    for integ in (sc.integrators if integrators is None else integrators):
        for hh in hs:
            try:
                out.append(symplecticity_error(scene, integ, hh, about=about, system=system))
            except ConfigError:
                if integrators is not None:
                    raise
                break
    return out
