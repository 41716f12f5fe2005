"""Issue 43, item 5: a joint placement's ZYZ angles, ``rotation = { zyz = [phi, theta, psi] }``.

DESIGN 4b: the child's frame at the joint's zero is the parent's turned by ``rotation``; DESIGN 2: ZYZ angles mean
``R = Rz(phi) @ Ry(theta) @ Rz(psi)``. With three non-zero, unequal angles every other order (Rz(psi) Ry(theta)
Rz(phi), the extrinsic reading, a sign) gives another rotation. Checked through the bodies' world attitudes
``<body>.q_world_*`` against scipy.spatial.transform.Rotation, built two ways (its intrinsic "ZYZ" Euler angles and
the product of the three elementary rotations): for a hinge (at its zero and while it turns), a ball, a fixed joint
and a root, under a parent that is itself turned.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

import gyrosim

PHI, THETA, PSI = 0.7, -1.1, 2.3   # rad: three non-zero, unequal angles
PARENT_Q = np.array([0.8, -0.2, 0.5, 0.26])   # the parent's start attitude (normalised below)
PARENT_Q = PARENT_Q / np.linalg.norm(PARENT_Q)
BALL_Q = np.array([0.9, 0.3, -0.2, 0.25])
BALL_Q = BALL_Q / np.linalg.norm(BALL_Q)
AXIS = np.array([0.0, 0.6, 0.8])   # the hinge's axis, in the parent's frame


def _zyz() -> Rotation:
    """Rz(phi) Ry(theta) Rz(psi), asserted equal two independent ways (scipy's intrinsic Euler angles; the product
    of elementary rotations)."""
    a = Rotation.from_euler("ZYZ", [PHI, THETA, PSI])
    b = (Rotation.from_rotvec([0.0, 0.0, PHI]) * Rotation.from_rotvec([0.0, THETA, 0.0])
         * Rotation.from_rotvec([0.0, 0.0, PSI]))
    assert np.allclose(a.as_matrix(), b.as_matrix(), rtol=0, atol=1e-15)
    return a


def _vec(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def _scene(tmp_path, child: str, root_rotation: bool = False) -> str:
    """A root ``base`` (ball at the origin, start attitude PARENT_Q, tumbling, no gravity) and its child ``part``
    placed with the ZYZ rotation; with ``root_rotation`` the root's own joint carries the rotation instead."""
    zyz = f"rotation = {{ zyz = {_vec([PHI, THETA, PSI])} }}\n"
    text = ('[scene]\nname = "zyz"\ng = 0.0\n'
            '[[body]]\nname = "base"\njoint = "ball"\nmass = 2.0\ninertia = { principal = [0.2, 0.3, 0.4] }\n'
            f'attitude = {{ q = {_vec(PARENT_Q)} }}\nrates = {{ omega = [0.4, -0.9, 1.3] }}\n'
            + (zyz if root_rotation else "")
            + '[[body]]\nname = "part"\nparent = "base"\n' + child + (zyz if not root_rotation else "")
            + 'position = [0.1, 0.2, -0.3]\nmass = 0.5\ncm = [0.02, 0.0, 0.01]\n'
              'inertia = { principal = [0.01, 0.02, 0.025] }\n')
    p = tmp_path / "zyz.toml"
    p.write_text(text)
    return str(p)


def _q(r, body, k=slice(None)):
    """A body's world attitude per row as scipy Rotations (the contract's (w, x, y, z) to scipy's order)."""
    return Rotation.from_quat(np.stack([r[f"{body}.q_world_{c}"][k] for c in "wxyz"], -1), scalar_first=True)


def _same(a: Rotation, b: Rotation, tol=1e-12):
    """The rotations agree to ``tol`` rad (the angle of a^-1 b): a few quaternion products' rounding, 1e-15."""
    ang = (a.inv() * b).magnitude()
    assert np.max(ang) < tol, np.max(ang)


def _run(path, T=1.0):
    return gyrosim.simulate(path, stop_time=T, output_interval=0.05, integrator="rk4", max_step=1e-3)


def test_the_reference_rotations_differ_in_the_wrong_orders():
    """The angles are such that the wrong orders are other rotations, far apart (so the tests below tell them
    apart): the reversed product and the extrinsic reading are more than 0.5 rad away."""
    R = _zyz()
    for wrong in (Rotation.from_euler("ZYZ", [PSI, THETA, PHI]), Rotation.from_euler("zyz", [PHI, THETA, PSI])):
        assert (R.inv() * wrong).magnitude() > 0.5


def test_hinge_child_at_zero_is_the_parent_turned_by_zyz(tmp_path):
    """A hinge starting at angle 0: the child's world attitude is the parent's times Rz(phi) Ry(theta) Rz(psi) at
    the start; along the run (the parent tumbling drags the hinge round; then a rate of 3 rad/s of its own), the
    parent's times R(axis, angle), axis in the parent's frame (DESIGN 4b), times the placement."""
    R = _zyz()
    r = _run(_scene(tmp_path, 'joint = "hinge"\naxis = ' + _vec(AXIS) + "\n"))
    assert r["part.angle"][0] == 0.0
    _same(_q(r, "part", 0), _q(r, "base", 0) * R)
    _same(_q(r, "part"), _q(r, "base") * Rotation.from_rotvec(np.outer(r["part.angle"], AXIS)) * R)
    r = _run(_scene(tmp_path, 'joint = "hinge"\naxis = ' + _vec(AXIS) + "\nrate = 3.0\n"))
    assert np.ptp(r["part.angle"]) > 1.0
    _same(_q(r, "part"), _q(r, "base") * Rotation.from_rotvec(np.outer(r["part.angle"], AXIS)) * R)


def test_ball_child_is_relative_to_the_turned_frame(tmp_path):
    """A ball child with start q: its world attitude is the parent's times the placement times its own q (DESIGN
    4b: a ball's q is relative to the turned frame), at the start and along the run (its q from the outputs)."""
    R = _zyz()
    r = _run(_scene(tmp_path, f'joint = "ball"\nattitude = {{ q = {_vec(BALL_Q)} }}\n'
                               'rates = { omega = [1.0, 0.5, -2.0] }\n'))
    _same(_q(r, "part", 0), _q(r, "base", 0) * R * Rotation.from_quat(BALL_Q, scalar_first=True))
    own = Rotation.from_quat(np.stack([r[f"part.q_{c}"] for c in "wxyz"], -1), scalar_first=True)
    _same(_q(r, "part"), _q(r, "base") * R * own)


def test_fixed_child_and_a_root_placement(tmp_path):
    """A fixed child is the parent turned by the placement at every row; a root whose joint carries the placement
    starts at R times its own start attitude (its frame at the joint's zero is the world's turned by R)."""
    R = _zyz()
    r = _run(_scene(tmp_path, 'joint = "fixed"\n'))
    _same(_q(r, "part"), _q(r, "base") * R)
    r = _run(_scene(tmp_path, 'joint = "fixed"\n', root_rotation=True), T=0.05)
    _same(_q(r, "base", 0), R * Rotation.from_quat(PARENT_Q, scalar_first=True))
