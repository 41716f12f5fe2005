"""Mode shapes on slider joints (issue 43, item 3): a slider's ``velocity`` is a rate, not a coordinate; the table's
shape column lists the largest components; the table and the plot number the modes alike.

The three masses between walls (mass_spring_chain: m = k = 1) have the closed-form shapes (1, sqrt 2, 1), (1, 0, -1)
and (1, -sqrt 2, 1) at w^2 = 2 - sqrt 2, 2, 2 + sqrt 2; the table prints 3 significant digits, so a component is
checked to the printed 0.707 (1/sqrt 2) and the shapes themselves to 1e-12 (exact derivatives, a 3 x 3 eigenproblem:
round-off of order 1e-16, seen 1e-15)."""
import math
import re

import numpy as np
import pytest

from gyrosim import Model
from gyrosim.analysis.linear_cli import displacements, plot_modes
from gyrosim.scene import scene_from_dict


def _shape_column(row: str) -> dict:
    """The table row's shape column as {name: printed value}."""
    shape = row.split(": ", 1)[1]
    return {n: float(v) for n, v in re.findall(r"(\S+) ([+-][0-9.]+)(?:,|$)", shape)}


def test_a_slider_velocity_is_a_rate():
    from gyrosim.analysis.linear import is_rate

    assert is_rate("m1.velocity") and is_rate("upper.rate") and is_rate("hub.omega_x") and is_rate("v_z")
    assert not is_rate("m1.displacement") and not is_rate("hub.rot_x") and not is_rate("orbit_anomaly")
    lin = Model("mass_spring_chain").linearize(about="equilibrium")
    for mode in lin.oscillations():
        assert displacements(mode.shape) == ["m1.displacement", "m2.displacement", "m3.displacement"]
        assert not any(is_rate(n) for n in mode.displacement_shape())
        flags = [is_rate(n) for n in mode.dominant(6)]
        assert flags == sorted(flags) and flags.count(False) >= 2  # coordinates first, then rates


def test_the_shape_column_lists_the_largest_components():
    """Issue 43: the column showed the first three states (m1.displacement, m1.velocity, m2.displacement), a
    velocity among them and the largest component third. Now the displacements only, largest first."""
    lin = Model("mass_spring_chain").linearize(about="equilibrium")
    rows = lin.table().splitlines()[1:]
    assert len(rows) == 3 and "velocity" not in lin.table()
    r = 1 / math.sqrt(2)  # the outer masses over the middle one in modes 1 and 3
    want = [{"m2.displacement": 1.0, "m1.displacement": r, "m3.displacement": r},
            {"m1.displacement": 1.0, "m3.displacement": -1.0},  # the middle mass at rest: not listed
            {"m2.displacement": 1.0, "m1.displacement": -r, "m3.displacement": -r}]
    for row, w in zip(rows, want):
        got = _shape_column(row)
        assert set(got) == set(w)
        assert next(iter(got)) == next(iter(w))  # the largest first (modes 1 and 3: the middle mass)
        for n, v in w.items():
            assert got[n] == pytest.approx(v, abs=5e-4)  # printed to 3 significant digits
    for mode, want in zip(lin.oscillations(), ([1, math.sqrt(2), 1], [1, 0, -1], [1, -math.sqrt(2), 1])):
        z = np.array([mode.shape[f"m{i}.displacement"] for i in (1, 2, 3)])
        z = z / z[0]  # the left mass moves in every mode
        np.testing.assert_allclose(z.real, want, atol=1e-12)
        assert np.max(np.abs(z.imag)) < 1e-12


def test_a_slider_with_gravity_and_a_spring_rests_at_mg_over_k(tmp_path):
    """A 2 kg mass on a vertical slider, spring 50 N/m, started moving at 0.4 m/s: the equilibrium search sets the
    velocity (a rate) to 0 and the mass at -m g / k = -0.3924 m; it swings at sqrt(k/m) = 5 rad/s."""
    m, k, g = 2.0, 50.0, 9.81
    sc = scene_from_dict({"scene": {"name": "spring_slider", "g": g},
                          "body": [{"name": "bob", "joint": "slider", "axis": [0.0, 0.0, 1.0], "mass": m,
                                    "inertia": {"principal": [0.0, 0.0, 0.0]}, "stiffness": k, "velocity": 0.4}]},
                         "<test>")
    model = Model(sc)
    lin = model.linearize(about="equilibrium")
    assert model.get("velocity") == 0.0
    assert model.get("displacement") == pytest.approx(-m * g / k, rel=1e-12)
    assert [x.frequency for x in lin.oscillations()] == pytest.approx([math.sqrt(k / m)], rel=1e-12)
    assert "velocity" not in lin.table()


def test_the_plot_numbers_the_modes_as_the_table(tmp_path):
    """Issue 43: the plot numbered the oscillations 1, 2, the table (with the molecule's rigid translation first)
    2, 3. Now both 2, 3; and the bars are the displacements only."""
    lin = Model("triatomic").linearize(about="equilibrium")
    numbers = [int(r.split()[0]) for r in lin.table().splitlines()[1:] if "oscillation" in r]
    assert numbers == [2, 3]
    fig = plot_modes(lin, tmp_path / "modes.png", title="triatomic")
    titles = [ax.get_title() for ax in fig.get_axes()[1:]]
    assert [int(re.match(r"mode (\d+):", t).group(1)) for t in titles] == numbers
    for ax in fig.get_axes()[1:]:
        labels = [t.get_text() for t in ax.get_yticklabels()]
        assert labels and not any("velocity" in s for s in labels)
