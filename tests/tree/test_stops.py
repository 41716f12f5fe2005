"""Impact stops at the end of a bouncing: the accumulation (Zeno) point of a mass dropped onto a stop, and what a
run reads there and after it (docs/engine.md, core/engine/tree.c advance_events)."""

from __future__ import annotations

import math

import pytest

from gyrosim.model import Model
from scene_examples import DROP

#: DROP's closed form: dropped from h0 = 1 m under g = 9.81 with restitution e = 0.8; the first impact at
#: t1 = v1 / g (v1 = sqrt(2 g h0)), then flights of 2 e^k v1 / g, k = 1, 2, ...: the impacts accumulate at
#: t1 + 2 e v1 / (g (1 - e)).
G, E, H0 = 9.81, 0.8, 1.0
V1 = math.sqrt(2 * G * H0)
T_ZENO = V1 / G + 2 * E * V1 / (G * (1 - E))


def _drop(tmp_path, integrator, max_step):
    path = tmp_path / f"drop_{integrator}.toml"
    path.write_text(DROP.format(integrator=integrator, max_step=max_step))
    return Model(str(path))


@pytest.mark.parametrize("integrator, max_step, window", [
    # rk4 and the implicit midpoint rules integrate a constant acceleration exactly and locate each impact as the
    # root of their one-step map: every bounce's time is the closed form's to round-off, and the flights shrink
    # geometrically down to a few ulp of the step, so the joint comes to rest within 1e-6 s of the closed form.
    ("rk4", 1e-3, 1e-6), ("midpoint", 1e-3, 1e-6), ("energy_momentum", 1e-3, 1e-6),
    # adaptive and dop853 locate each impact to their tolerance (1e-12 here): each bounce time to ~1e-9 s and the
    # accumulation to 1e-6 s (the errors of ~30 resolved bounces add up).
    ("dop853", 0.1, 1e-6), ("adaptive", 0.1, 1e-6)])
def test_a_bouncing_mass_comes_to_rest_at_the_accumulation_point(tmp_path, integrator, max_step, window):
    """Before the closed form's accumulation time the mass still flies (a rate, a height above the stop); from it on
    it rests on the stop: displacement = the limit and rate = 0, exactly, for the rest of the run, its energy 0 and
    the energy the impacts (and the plastic end of the sequence) took off booked in the balance: energy_error at
    the integrator's round-off (1e-12 of the start energy)."""
    m = _drop(tmp_path, integrator, max_step)
    E0 = m.get("energy")
    m.step(T_ZENO - 10 * window)
    assert m.get("velocity") != 0.0 or m.get("displacement") > 0.0
    m.step(20 * window)
    for _ in range(30):   # and it stays there, step after step
        assert m.get("displacement") == 0.0 and m.get("velocity") == 0.0
        assert m.get("energy") == 0.0
        assert abs(m.get("energy_error")) < 1e-12 * E0
        m.step(0.1)


def test_before_the_accumulation_the_bounces_follow_the_closed_form(tmp_path):
    """The resting rule does not touch a resolved bounce: rk4 at 1 ms steps reads the closed form's apex heights
    e^(2k) h0 (k = 1..10, the last 1.2e-2 mm) to 1e-12 m, at the closed form's apex times."""
    m = _drop(tmp_path, "rk4", 1e-3)
    t = V1 / G
    for k in range(1, 11):
        v = E ** k * V1
        apex = t + v / G
        m.step(apex - m.time)
        assert m.get("displacement") == pytest.approx(E ** (2 * k) * H0, abs=1e-12)
        assert abs(m.get("velocity")) < 1e-11
        t += 2 * v / G


@pytest.mark.parametrize("integrator", ["adaptive", "dop853", "rk4"])
@pytest.mark.parametrize("max_step", [0.001, 0.01, 0.5])
def test_one_long_call_across_the_accumulation_point_comes_to_rest(tmp_path, integrator, max_step):
    """A call of 0.5 s that spans the accumulation point: the flights shrink towards it within the call, and the
    controller's step after each impact is the smooth motion's again (not the shrinking step that reached the stop,
    which once collapsed the adaptive methods' steps until they failed); the run ends at rest with the balance
    at round-off (1e-12 of E0)."""
    import gyrosim

    path = tmp_path / "drop.toml"
    path.write_text(DROP.format(integrator=integrator, max_step=max_step))
    r = gyrosim.simulate(str(path), stop_time=10.0, output_interval=0.5)
    late = r["time"] > T_ZENO
    assert (r["displacement"][late] == 0.0).all() and (r["velocity"][late] == 0.0).all()
    assert abs(r["energy_error"]).max() < 1e-12 * G * H0


def test_an_impact_at_a_steps_end_or_a_start_on_the_stop_bounces(tmp_path):
    """A cart at 1 m/s onto a wall 0.5 m away (e = 0.9), in steps of 0.1 s that end exactly on it: it comes back
    at -0.9 m/s (it stuck to the wall when a step's end on the stop was taken as rest), its energy 0.405 J. A mass
    started on its stop moving in at 3 m/s leaves it at 0.8 x 3 m/s."""
    (tmp_path / "wall.toml").write_text("""
[scene]
name = "wall"
g = 0.0
integrator = "rk4"
max_step = 0.1
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.0
inertia = { principal = [0.0, 0.0, 0.0] }
velocity = 1.0
upper = 0.5
stop = "impact"
restitution = 0.9
""")
    m = Model(str(tmp_path / "wall.toml"))
    for _ in range(8):
        m.step(0.1)
    assert m.get("velocity") == -0.9 and m.get("displacement") == pytest.approx(0.5 - 0.9 * 0.3, abs=1e-15)
    assert m.get("energy") == pytest.approx(0.5 * 0.81, rel=1e-15) and abs(m.get("energy_error")) < 1e-15
    path = tmp_path / "drop.toml"
    path.write_text(DROP.format(integrator="rk4", max_step=1e-3))
    m = Model(str(path), parameters={"displacement": 0.0, "velocity": -3.0})
    m.step(1e-3)
    assert m.get("velocity") == pytest.approx(2.4 - 9.81e-3, abs=1e-15)


@pytest.mark.parametrize("integrator, max_step", [("rk4", 0.01), ("adaptive", 0.5), ("dop853", 0.01)])
def test_a_fast_elastic_rattle_keeps_its_energy(tmp_path, integrator, max_step):
    """A cart at 10 m/s between stops 1 mm apart (e = 1): 100 impacts in each 0.01 s step, none of them an
    accumulation point; after 0.1 s its speed is still 10 m/s and its energy 50 J (it was stopped dead once a
    piece had more than 64 impacts)."""
    (tmp_path / "rattle.toml").write_text(f"""
[scene]
name = "rattle"
g = 0.0
integrator = "{integrator}"
max_step = {max_step}
[[body]]
name = "cart"
joint = "slider"
axis = [1.0, 0.0, 0.0]
mass = 1.0
inertia = {{ principal = [0.0, 0.0, 0.0] }}
velocity = 10.0
lower = -0.0005
upper = 0.0005
stop = "impact"
restitution = 1.0
""")
    m = Model(str(tmp_path / "rattle.toml"))
    for _ in range(10):
        m.step(0.01)
    assert abs(m.get("velocity")) == pytest.approx(10.0, rel=1e-12)
    assert m.get("energy") == pytest.approx(50.0, rel=1e-12) and abs(m.get("energy_error")) < 1e-9


def test_a_mass_resting_on_its_stop_reads_its_support(tmp_path):
    """At rest on the stop (after the accumulation point, or started there) the stop holds the mass: an
    accelerometer on it reads +g up (the stop's reaction as a generalized force, Model.specific_force), not the
    free fall it read while the contact was only impulses; in flight it reads 0."""
    path = tmp_path / "drop.toml"
    path.write_text(DROP.format(integrator="rk4", max_step=1e-3))
    m = Model(str(path))
    assert list(m.specific_force("ball")) == [0.0, 0.0, 0.0]   # falling
    m.step(T_ZENO + 0.5)
    assert list(m.specific_force("ball")) == [0.0, 0.0, G]
    m = Model(str(path), parameters={"displacement": 0.0})
    assert list(m.specific_force("ball")) == [0.0, 0.0, G]
