"""Gimbal lock is named only where a gimbal lines two axes up: not for a planar chain, whose hinges are parallel by
design (their axes line up in every state and nothing is singular)."""

from __future__ import annotations

from gyrosim.model import Model


def test_a_planar_chain_is_not_in_gimbal_lock():
    for name in ("double_pendulum", "coupled_pendula"):
        m = Model(name)
        m.step(0.1)
        assert m.gimbal_lock() is None, name


def test_a_gimbal_at_its_singular_angle_is():
    """gimbal_gyroscope with the inner gimbal at 0: the outer (world z) and rotor (inner's z) axes line up across
    the inner gimbal's x axis."""
    m = Model("gimbal_gyroscope", parameters={"inner.angle": 0.0})
    assert "gimbal lock" in m.gimbal_lock() and "'outer' and 'rotor'" in m.gimbal_lock()
    m = Model("gimbal_gyroscope", parameters={"inner.angle": 0.5})
    assert m.gimbal_lock() is None
