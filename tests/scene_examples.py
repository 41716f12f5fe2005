"""Scenes and closed forms that the tests of the joints and elements share (tests/tree/test_elements.py, the FMU and
service tests): docs/scenes.md's examples by name, and a mass bouncing on an impact stop with its closed form."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

PAGE = Path(__file__).resolve().parents[1] / "docs" / "scenes.md"
#: docs/scenes.md's TOML examples, in their order
BLOCKS = re.findall(r"^```toml\n(.*?)^```", PAGE.read_text(), re.S | re.M)


def doc_scene(name: str) -> str:
    """docs/scenes.md's TOML example of scene ``name``."""
    return next(b for b in BLOCKS if re.search(rf'^name = "{name}"$', b, re.M))


#: A mass dropped from 1 m onto an impact stop (restitution 0.8) under g = 9.81 along -z; ``{integrator}`` and
#: ``{max_step}`` to fill.
DROP = """
[scene]
name = "drop"
gravity = [0.0, 0.0, -9.81]
integrator = "{integrator}"
max_step = {max_step}
tolerance = 1e-12
[[body]]
name = "ball"
joint = "slider"
axis = [0.0, 0.0, 1.0]
mass = 1.0
inertia = {{ principal = [0.0, 0.0, 0.0] }}
displacement = 1.0
lower = 0.0
stop = "impact"
restitution = 0.8
"""


#: A mass on a vertical slider between impact stops at 0 and 10 m, resting on nothing at 1 m (the issue's case).
SLIDER = """
[scene]
name = "stops"
gravity = [0.0, 0.0, -9.81]
integrator = "rk4"
max_step = 0.001
[[body]]
name = "ball"
joint = "slider"
axis = [0.0, 0.0, 1.0]
mass = 1.0
inertia = {{ principal = [0.0, 0.0, 0.0] }}
displacement = {x0}
lower = {lower}
upper = {upper}
stop = "impact"
restitution = 0.8
"""


def bounce(t, h0=1.0, g=9.81, e=0.8):
    """The bouncing mass's height and velocity at t: free fall from h0, each impact v -> -e v."""
    v = np.sqrt(2 * g * h0)
    t1 = v / g
    if t < t1:
        return h0 - 0.5 * g * t * t, -g * t
    t -= t1
    while True:
        v *= e
        if t < 2 * v / g:
            return v * t - 0.5 * g * t * t, v - g * t
        t -= 2 * v / g
