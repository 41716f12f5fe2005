"""FMUs of a scene with contact (a ball on a compliant floor with friction, DESIGN 4b "Contact"): the one glue runs
it to gyrosim.simulate's bits in co-simulation (FMI 2.0 and 3.0, FMPy), the plane's parameters are FMU parameters
checked by the model's ranges, and model exchange under CVode meets a tight model run within 1e-6."""

from __future__ import annotations

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

import gyrosim
from gyrosim.fmu import build_fmu
from gyrosim.kernel_tree import tree_output_names
from gyrosim.scene import load_scene

DYADIC = 2.0 ** -7   # s: FMPy's step sizes are exactly dt (tests/fmu/test_fmu_tree.py)
VERSIONS = (2, 3)

#: A ball rolling out of a slide on a soft floor (stiff enough to rest 0.1 mm deep; soft enough for CVode in model
#: exchange), with spin friction and rolling resistance so that every term of the law is in the bits.
BALL = """
[scene]
name = "contact_ball"
integrator = "rk4"
max_step = 0.0009765625

[[body]]
name = "ball"
joint = "free"
mass = 0.17
inertia = { principal = [5.55e-5, 5.55e-5, 5.55e-5] }
r = [0, 0, 0.0284]
v = [1.0, 0, 0]
rates = { omega = [0, 0, 20.0] }

[[shape]]
name = "surface"
body = "ball"
kind = "sphere"
radius = 0.028575

[[plane]]
name = "floor"
model = "compliant"
stiffness = 1e6
damping = 2.0
friction = 0.2
friction_model = "regularized"
slip_velocity = 0.01
spin_radius = 0.002
rolling_resistance = 0.0005
"""


@pytest.fixture(scope="module")
def ball(tmp_path_factory):
    d = tmp_path_factory.mktemp("contact_fmu")
    toml = d / "ball.toml"
    toml.write_text(BALL)
    return toml, {v: build_fmu(str(toml), v, d / f"fmi{v}", fmi_type="both", windows=False) for v in VERSIONS}


@pytest.mark.parametrize("v", VERSIONS)
def test_contact_scene_runs_to_the_bits_in_co_simulation(ball, v):
    toml, fmus = ball
    names = tree_output_names(load_scene(str(toml)))
    assert "surface.normal_force" in names and "surface.mode" in names
    start = {"floor.friction": 0.3, "floor.spin_radius": 0.003}
    ref = gyrosim.simulate(str(toml), stop_time=0.5, output_interval=DYADIC, start_values=start)
    # the slide is over by the end (t* = 2 v0 / (7 mu g) = 0.1 s): the contact point creeps below slip_velocity
    assert ref["surface.slip_speed"][-1] < 0.01 < ref["surface.slip_speed"][0]
    assert validate_fmu(str(fmus[v])) == []
    md = {x.name: x for x in read_model_description(str(fmus[v])).modelVariables}
    assert md["floor.friction"].causality == "parameter" and md["surface.gap"].causality == "output"
    assert md["floor.stiffness"].unit == "N/m1.5"
    r = simulate_fmu(str(fmus[v]), stop_time=0.5, output_interval=DYADIC, start_values=start, output=names)
    for n in names:
        assert np.array_equal(r[n], ref[n]), n


@pytest.mark.parametrize("v", VERSIONS)
def test_plane_parameters_are_checked_in_the_fmu_as_in_the_model(ball, v):
    _, fmus = ball
    log = []

    def logger(*args):
        msg = args[-1]
        log.append(msg.decode() if isinstance(msg, bytes) else str(msg))

    with pytest.raises(FMICallException):
        simulate_fmu(str(fmus[v]), start_values={"floor.slip_velocity": 0.0}, stop_time=0.1, logger=logger)
    assert any("floor.slip_velocity" in m for m in log), log


def test_contact_scene_in_model_exchange_meets_a_tight_run(ball):
    """CVode at 1e-10 against dop853 at 1e-12: the law is smooth (C1 at touch-down: F ~ delta^1.5), no events. The
    normal force is the contact stiffness (dF/d delta = 1.5 k delta^0.5, about 2e4 N/m here) times the position's
    error: 1e-6 relative in positions and rates, 1e-5 in the force."""
    toml, fmus = ball
    names = ["r_x", "v_x", "omega_z", "surface.normal_force", "surface.slip_speed"]
    tight = gyrosim.simulate(str(toml), stop_time=0.3, output_interval=0.01, integrator="dop853",
                             relative_tolerance=1e-12, max_step=1.0)
    r = simulate_fmu(str(fmus[2]), fmi_type="ModelExchange", stop_time=0.3, output_interval=0.01,
                     relative_tolerance=1e-10, output=names)
    for n in names:
        tol = 1e-5 if n == "surface.normal_force" else 1e-6
        assert np.abs(r[n] - tight[n]).max() < tol * max(1.0, np.abs(tight[n]).max()), n


def test_rigid_contact_fmu_jacobian_at_the_start_is_the_engines(tmp_path):
    """The tippe top on its rigid floor (sliding and spinning: the normal row with Coulomb-Contensou friction on its
    column): the model-exchange FMU's directional derivatives at the start, along omega_x, are
    gyrosim.core._engine.tree_directional's in Python on the start state with the start's modes (tree_start makes
    them, as the FMU's initialisation does), to the bit; and the contact shows in them: the centre's accelerations
    along y (the friction's) and z (the normal force's) move with the spin."""
    from fmpy import extract
    from fmpy.fmi2 import FMU2Model

    from gyrosim.core import _engine
    from gyrosim.kernel_tree import tree_layout

    path = build_fmu("tippe_top", 2, tmp_path, fmi_type="me", windows=False)
    md = read_model_description(str(path))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    f = FMU2Model(guid=md.guid, unzipDirectory=extract(str(path), unzipdir=str(tmp_path / "x")),
                  modelIdentifier=md.modelExchange.modelIdentifier, instanceName="top")
    f.instantiate()
    f.setupExperiment(startTime=0.0)
    f.enterInitializationMode()
    f.exitInitializationMode()
    ders = [f"der({n})" for n in ("omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z")]
    got = f.getDirectionalDerivative([vr[d] for d in ders], [vr["omega_x"]], [1.0])
    f.terminate()
    f.freeInstance()
    sc = load_scene("tippe_top")
    lay = tree_layout(sc)
    p = lay.params(float(sc.g), float(sc.max_drift))
    y = lay.state().copy()
    _engine.tree_start(lay.desc, y.reshape(1, -1), p.reshape(1, -1))
    vy = np.zeros(lay.nx)
    vy[lay.coord_slots[(0, "omega_x")]] = 1.0
    ddy, dout = np.zeros(lay.nx + 1), np.zeros(lay.nout)
    _engine.tree_directional(lay.desc, y.reshape(1, -1), p.reshape(1, -1), vy, np.zeros(lay.np), ddy, dout)
    want = [ddy[lay.coord_slots[(0, n)]] for n in ("omega_x", "omega_y", "omega_z", "v_x", "v_y", "v_z")]
    assert got == want
    assert want[4] != 0.0 and want[5] != 0.0   # v_y (the friction's), v_z (the normal force's)
