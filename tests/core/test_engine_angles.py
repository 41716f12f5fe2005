"""The engine's ZYZ angle outputs (phi, theta, psi) against numpy's arctan2 on many attitudes.

The engine computes them with its own inline atan2 (Cephes' atan, angles.h ``gs_atan2``) instead of libm's; within
2 ulp of the correctly rounded atan2 (measured on 20 million pairs), so theta = 2 atan2(|(x, y)|, |(w, z)|) agrees
with numpy's to a few ulp of pi and phi, psi (unwrapped from reference angles) to a few ulp of their size. Zeros,
signed zeros, the gimbal-lock attitudes (theta = 0 and pi) and non-finite quaternions keep IEEE atan2's values.
"""
import numpy as np
import pytest

from gyrosim.core import _engine

# a few ulp of the angle's size: theta is at most pi, phi and psi here at most a few 2 pi
ULP_PI = np.spacing(np.pi)


def _outputs(q, ref=(0.0, 0.0)):
    q = np.atleast_2d(np.asarray(q, dtype=float))
    n = len(q)
    y = np.zeros((n, _engine.NY))
    y[:, :4] = q
    y[:, 4:7] = (0.3, -0.2, 0.1)
    y[:, 7], y[:, 8] = ref
    p = np.zeros((n, _engine.NP))
    p[:, :3] = (1.0, 2.0, 3.0)
    out = np.zeros((n, _engine.NOUT))
    _engine.outputs(y, p, out)
    return out[:, 7], out[:, 8], out[:, 9]


def _wrap(a):
    return a - 2 * np.pi * np.floor((a + np.pi) / (2 * np.pi))


def _expected(q, ref):
    w, x, y, z = q.T
    hs, hd = np.arctan2(z, w), np.arctan2(-x, y)
    theta = 2.0 * np.arctan2(np.hypot(x, y), np.hypot(w, z))
    phi0, psi0 = ref
    return phi0 + _wrap(hs + hd - phi0), theta, psi0 + _wrap(hs - hd - psi0)


def test_angles_agree_with_numpy_on_random_attitudes():
    rng = np.random.default_rng(7)
    q = rng.normal(size=(200_000, 4))
    q /= np.linalg.norm(q, axis=1)[:, None]
    # attitudes near the axes and the octant boundaries (|x| = |y|, |w| = |z|), where the reduction switches
    q[:1000, 1:3] *= 1e-9
    q[1000:2000, [0, 3]] *= 1e-9
    q[2000:3000, 2] = q[2000:3000, 1] * (1 + 1e-15)
    q[3000:4000, 3] = -q[3000:4000, 0]
    q /= np.linalg.norm(q, axis=1)[:, None]
    for ref in ((0.0, 0.0), (7.5, -13.0)):
        phi, theta, psi = _outputs(q, ref)
        e_phi, e_theta, e_psi = _expected(q, ref)
        # theta: within 4 ulp of pi (atan2 2 ulp, the norms 1 ulp each, times 2)
        assert np.max(np.abs(theta - e_theta)) <= 4 * ULP_PI
        # phi, psi: hs +- hd (each within 2 ulp of pi) and the reference's wrap, a few ulp of the result
        scale = np.maximum(np.abs(e_phi), np.pi)
        assert np.max(np.abs(phi - e_phi) / np.spacing(scale)) <= 8
        scale = np.maximum(np.abs(e_psi), np.pi)
        assert np.max(np.abs(psi - e_psi) / np.spacing(scale)) <= 8


@pytest.mark.parametrize("q, theta", [
    ((1.0, 0.0, 0.0, 0.0), 0.0),
    ((0.0, 1.0, 0.0, 0.0), np.pi),
    ((0.0, 0.0, -1.0, 0.0), np.pi),
    ((0.0, 0.0, 0.0, 1.0), 0.0),
    ((-1.0, -0.0, 0.0, -0.0), 0.0),
    ((np.sqrt(0.5), np.sqrt(0.5), 0.0, 0.0), np.pi / 2),
    ((0.5, 0.5, -0.5, 0.5), np.pi / 2),
])
def test_special_attitudes(q, theta):
    phi, th, psi = _outputs(q)
    assert th[0] == pytest.approx(theta, abs=2 * ULP_PI)
    # phi and psi finite and the attitude rebuilt from them is q (up to sign)
    assert np.isfinite(phi[0]) and np.isfinite(psi[0])
    from gyrosim.core.rotations import euler_zyz_to_quat
    r = euler_zyz_to_quat(phi[0], th[0], psi[0])
    assert min(np.linalg.norm(r - q), np.linalg.norm(r + q)) < 1e-15


def test_a_quarter_turn_about_z_gives_atan2s_exact_values():
    # atan2 of equal magnitudes is pi/4 to the ulp (the octant's boundary): phi + psi = pi/2 about z
    c = np.sqrt(0.5)
    phi, theta, psi = _outputs((c, 0.0, 0.0, c))
    assert theta[0] == 0.0
    assert phi[0] + psi[0] == pytest.approx(np.pi / 2, abs=2 * ULP_PI)


def test_non_finite_attitudes_give_nan_angles():
    phi, theta, psi = _outputs([(np.nan, 0.0, 0.0, 1.0), (0.0, np.nan, 0.0, 0.0)])
    assert np.isnan(theta).all()
    assert np.isnan(phi).all() and np.isnan(psi).all()


def test_signed_zeros_in_the_attitude_keep_atan2s_exact_values():
    # components -0.0 and +0.0: atan2(1, -0.0) is pi/2 to the bit (the octant and the quadrant in one sum), so the
    # angles of a quarter turn about x with a negative zero are those with a positive one
    c = np.sqrt(0.5)
    a = _outputs((c, c, 0.0, 0.0))
    b = _outputs((c, c, -0.0, 0.0))
    for u, v in zip(a, b):
        np.testing.assert_array_equal(u, v)
    phi, theta, psi = _outputs((0.0, 0.0, -0.0, 1.0))  # theta = 0, phi + psi = pi (wrapped to -pi)
    assert abs(phi[0] + psi[0]) == np.pi and theta[0] == 0.0


@pytest.mark.parametrize("tilt", [1e-100, 1e-150, 1e-160, 1e-170, 1e-200, 1e-300, 1e-320])
def test_tiny_tilts_keep_their_theta(tilt):
    # an attitude tilted by theta from the vertical (a quarter of it about x, the rest about y, then a turn about z):
    # the squares of its components underflow below about 1e-154, and theta is still theta to a few ulp of itself,
    # not 0 (and the tilt at pi, upside down, is pi - theta: pi to the ulp at these sizes)
    half = 0.5 * tilt
    for w, z in ((1.0, 0.0), (np.sqrt(0.5), np.sqrt(0.5))):
        q = (w, 0.6 * half * w, 0.8 * half * w, z) if z == 0.0 else (w, 0.6 * half, 0.8 * half, z)
        phi, theta, psi = _outputs(q)
        assert theta[0] == pytest.approx(tilt, rel=8 * np.finfo(float).eps, abs=4 * 5e-324)
        assert np.isfinite(phi[0]) and np.isfinite(psi[0])
    phi, theta, psi = _outputs((0.6 * half, 1.0, 0.0, 0.8 * half))
    assert theta[0] == pytest.approx(np.pi, abs=2 * ULP_PI)
