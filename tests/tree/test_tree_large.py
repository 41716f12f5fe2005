"""Trees beyond the small build's 32 bodies (engine/tree_big.c: the per-body tables sized by the tree, from a
thread-local arena): chains of 200 links and a random tree of 1,000 bodies against Pinocchio, the energy balance
of a few rk4 steps, the linearization of a 50-link chain, and the implicit methods' refusal beyond their size.

Tolerances as tests/tree/test_tree_engine.py: accelerations, energy and momentum against Pinocchio to 1e-10 of the
largest value (both exact algorithms in double precision).
"""

import numpy as np
import pytest
from test_tree_engine import G, _close, _layout

from gyrosim.core import _engine
from gyrosim.errors import ConfigError
from gyrosim.model import Model
from gyrosim.scene import scene_from_dict

pr = pytest.importorskip("pin_reference", reason="Pinocchio (pin) is a test dependency")


def _chain(rng, n, joint):
    """n links, each hanging from the one before through `joint` about 0.1 m below its joint point, random axes,
    masses and inertias whose principal moments are within a factor 3 of each other: a well-conditioned chain (random
    thin links make the mass matrix of a long chain of balls so ill-conditioned that double precision does not
    determine its accelerations: two exact algorithms then differ by more than the tolerance)."""
    bodies = []
    for i in range(n):
        mass = float(rng.uniform(0.5, 2.0))
        R = pr.quat_to_matrix(pr.random_rotation(rng))
        J = R @ np.diag(rng.uniform(1.0, 3.0, 3) * 1e-2 * mass) @ R.T
        pos = np.array([0.0, 0.0, -0.1 if i else 0.0]) + rng.uniform(-0.02, 0.02, 3)
        cm = np.array([0.0, 0.0, -0.05]) + rng.uniform(-0.02, 0.02, 3)
        bodies.append({"parent": i - 1, "joint": joint, "pos": pos, "axis": pr._random_unit(rng), "mass": mass,
                       "cm": cm, "inertia": J})
    return bodies


def _pin_accelerations(bodies, state):
    """Pinocchio's joint accelerations of a chain of hinges or balls in gyrosim's coordinates, from pin_reference's
    model: for hinges its articulated-body algorithm (pin.aba); for balls its composite-rigid-body mass matrix and
    nonlinear effects (pin.crba, pin.nonLinearEffects) solved densely. Pinocchio's ABA loses the ball chain: 5e-9
    of the largest value at 30 links, all of it from 60 (and it slows down by orders of magnitude: its recursion
    runs into huge intermediates), while its CRBA and gyrosim's ABA agree to 4e-11 at 200 links (the mass matrix's
    condition number is 5e7 there)."""
    import pinocchio as pin

    model, slots = pr.build_model(bodies, G)
    data = model.createData()
    q, v, tau = pr._pack(bodies, model, slots, state, None)
    if all(b["joint"] == "hinge" for b in bodies):
        ddq = np.array(pin.aba(model, data, q, v, tau))
    else:
        M = np.array(pin.crba(model, data, q))
        M = np.triu(M) + np.triu(M, 1).T   # crba fills the upper triangle
        ddq = np.linalg.solve(M, tau - np.array(pin.nonLinearEffects(model, data, q, v)))
    return np.concatenate([ddq[s.idx_v:s.idx_v + (1 if b["joint"] == "hinge" else 3)]
                           for b, s in zip(bodies, slots, strict=True)])


def _compare_accelerations(bodies, rng, states=2):
    for _ in range(states):
        state = pr.random_state(bodies, rng)
        for s in state:   # relative rates of 0.1-1 rad/s: a 200-link chain's tip then turns at tens of rad/s
            for k in ("omega", "rate"):
                if k in s:
                    s[k] = 0.1 * np.asarray(s[k]) if k == "omega" else 0.1 * s[k]
        lay = _layout(bodies, state)
        p = lay.params(G, 0.0)
        qdd = np.zeros(lay.dof)
        _engine.tree_accelerations(lay.desc, lay.state(), p, qdd)
        _close(qdd, _pin_accelerations(bodies, state))


@pytest.mark.parametrize(("joint", "n"), [("hinge", 200), ("ball", 64)])
def test_long_chains_equal_pinocchio(joint, n):
    """A 200-link chain of hinges and a 64-link chain of balls (both beyond the small build's 32 bodies) at random
    states: the joint accelerations equal Pinocchio's. The ball chain is shorter because Pinocchio's
    Model.createData alone takes 34 s for 200 ball joints (its cost grows as the cube of the depth); gyrosim's
    accelerations of the 200-ball chain were checked against its CRBA once (4e-11 of the largest value)."""
    rng = np.random.default_rng(200 + (joint == "ball"))
    bodies = _chain(rng, n, joint)
    assert len(bodies) > _engine.TREE_SMALL
    _compare_accelerations(bodies, rng)


def _bushy(rng, n):
    """pin_reference.random_tree with every parent uniform among the earlier bodies (depth ~ ln n)."""
    bodies = pr.random_tree(rng, n, root_joint="ball")
    for i, b in enumerate(bodies[1:], 1):
        b["parent"] = int(rng.integers(0, i))
    return bodies


def test_random_tree_of_100_bodies_energy_and_momentum_equal_pinocchio():
    """A random tree of 100 bodies (hinge, ball, free_rotation, fixed): energy and angular momentum equal
    Pinocchio's at a random state. (Pinocchio's Model.createData takes 46 s for 300 such bodies and fails with a
    MemoryError at 1,000: the 1,000-body tree is checked by its energy balance below.)"""
    rng = np.random.default_rng(300)
    bodies = _bushy(rng, 100)
    state = pr.random_state(bodies, rng)
    lay = _layout(bodies, state)
    out = np.empty(lay.nout)
    _engine.tree_outputs(lay.desc, lay.state(), lay.params(G, 0.0), out)
    _close(out[-5], pr.energy(bodies, G, state))
    _close(out[-3:], pr.momentum_world(bodies, state))


def test_random_tree_of_1000_bodies_rk4_keeps_the_energy_balance():
    """A random tree of 1,000 bodies: 20 rk4 steps of 1e-5 s keep the energy balance (energy_error, the health
    monitor's E - E0 - W) below 1e-9 of the energy scale, and the state finite."""
    rng = np.random.default_rng(1000)
    bodies = _bushy(rng, 1000)
    state = pr.random_state(bodies, rng)
    lay = _layout(bodies, state)
    p = lay.params(G, 0.0)
    y = lay.state()[None, :].copy()
    hint, stats, status = np.zeros(1), np.zeros((1, 3), dtype=np.int64), np.zeros(1, dtype=np.int32)
    P = p[None, :].copy()
    P[0, _engine.TP_DRIFT] = 0.0
    _engine.tree_start(lay.desc, y, P)   # the health monitor's start values (E0, the scales)
    failed = _engine.tree_advance(lay.desc, _engine.METHODS.index("rk4"), y, P, 20 * 1e-5, 0.0, 0.0, 1e-5, hint,
                                  stats, status, 1)
    assert failed == 0 and stats[0, 0] == 20
    out = np.empty(lay.nout)
    _engine.tree_outputs(lay.desc, y[0], p, out)
    assert np.all(np.isfinite(out))
    assert abs(out[-4]) < 1e-9 * y[0, lay.nx + 1]


def _chain_scene(n, integrator="rk4", joint="hinge", bent=True):
    bodies = []
    for i in range(n):
        b = {"name": f"link{i}", "joint": joint, "mass": 0.5, "cm": [0.0, 0.0, -0.05],
             "inertia": {"principal": [1e-3, 1e-3, 2e-4]}}
        if joint == "hinge":
            b.update(axis=[0.0, 1.0, 0.0], angle=0.1 * np.sin(i) if bent else 0.0)
        if i:
            b.update(parent=f"link{i - 1}", position=[0.0, 0.0, -0.1])
        bodies.append(b)
    return scene_from_dict({"scene": {"name": f"chain{n}", "integrator": integrator, "max_step": 1e-3,
                                      "stop_time": 0.01, "output_interval": 0.005}, "body": bodies})


def test_linearize_a_50_link_chain():
    """Model.linearize of a 50-link hanging chain about its state at rest straight down: A is 100 x 100, its
    position block the identity (angle' = rate), and its eigenvalues purely imaginary pairs (a conservative
    pendulum about a stable equilibrium: the frequencies of its normal modes)."""
    m = Model(_chain_scene(50, bent=False))
    m.initialize()
    A, B, C, D, names = m.linearize()
    assert A.shape == (100, 100)
    ang = [names["states"].index(f"link{i}.angle") for i in range(50)] if isinstance(names, dict) else None
    if ang is not None:
        rate = [names["states"].index(f"link{i}.rate") for i in range(50)]
        np.testing.assert_array_equal(A[np.ix_(ang, rate)], np.eye(50))
    ev = np.linalg.eigvals(A)
    assert np.max(np.abs(ev.real)) < 1e-6 * np.max(np.abs(ev))
    assert np.min(np.abs(ev.imag)) > 0.0


@pytest.mark.parametrize("integ", ["midpoint", "energy_momentum"])
def test_implicit_methods_refused_beyond_their_size(integ):
    """A 300-link chain (600 joint coordinates) asks for an implicit method: a ConfigError naming the integrator,
    the value and the largest size they take (their dense Newton matrix); rk4 runs it."""
    with pytest.raises(ConfigError, match=rf"integrator.*{integ}.*at most {_engine.IMPLICIT_MAX - 1} joint"):
        _chain_scene(300, integ)
    m = Model(_chain_scene(300))
    m.initialize()
    with pytest.raises(ConfigError, match=rf"integrator.*{integ}.*Newton matrix is dense"):
        m.set("integrator", integ)
