"""``gyrosim hamiltonian SCENE``: a scene's canonical momenta and Hamiltonian at its start state, and the
symplecticity error of its integrators' one-step maps (:mod:`gyrosim.analysis.hamilton`)."""
from __future__ import annotations

import math


def register(subparsers) -> None:
    from ..cli import SCENE_HELP, add_verbosity

    p = subparsers.add_parser(
        "hamiltonian", help="canonical momenta, H, and how symplectic each integrator's step is",
        description="Print a scene's momenta conjugate to its coordinates (<body>.p_angle per hinge, "
                    "<body>.p_rot_x..z = dT/domega in the body frame per rotating joint, <body>.p_r_x..z per free "
                    "joint; exact, from the engine's complex step) and its Hamiltonian H = T + V at the start state "
                    "(after --set/--start-values), then the symplecticity error max |M^T J M - J| of one step of "
                    "each integrator the scene takes (or those given) with the measurement's floor: a symplectic "
                    "map is at the floor, rk4's defect falls as h^5.",
        epilog="Examples: 'gyrosim hamiltonian heavy_top', 'gyrosim hamiltonian double_pendulum --step 0.01 "
               "--step 0.005 --integrator rk4'.")
    p.add_argument("scene", help=SCENE_HELP)
    p.add_argument("--set", action="append", metavar="NAME=VALUE", help="set a parameter or start value (repeatable)")
    p.add_argument("--start-values", nargs="+", action="extend", metavar="NAME VALUE",
                   help="name-value pairs of start values, as FMPy takes them")
    p.add_argument("--integrator", action="append", metavar="NAME",
                   help="measure this integrator (repeatable; default every one the scene takes)")
    p.add_argument("--step", action="append", type=float, metavar="H",
                   help="one internal step of H s (repeatable; default the scene's max_step)")
    add_verbosity(p)
    p.set_defaults(func=cmd_hamiltonian)


def cmd_hamiltonian(args) -> int:
    from ..cli import _start_values, verbosity
    from ..errors import ConfigError
    from ..model import Model
    from ..trajectory import apply_overrides
    from .hamilton import CanonicalChart, hamiltonian, symplecticity_error

    v = verbosity(args)
    m = Model(args.scene)
    apply_overrides(m, _start_values(args))
    m.initialize()
    steps = args.step or [m.max_step]
    for h in steps:
        if not (math.isfinite(h) and h > 0):
            raise ConfigError("--step", h, "a finite step > 0 in s")
    allowed = list(m.scene.integrators)
    for integ in args.integrator or ():
        if integ not in allowed:
            raise ConfigError("--integrator", integ, "one of the scene's integrators: " + ", ".join(allowed))
    integrators = args.integrator or allowed
    ch = CanonicalChart(m)
    units = {"angle": "kg*m^2/s", "rotation": "kg*m^2/s", "length": "kg*m/s"}
    if v >= 0:
        print(f"scene {m.scene.name}: {ch.n} degrees of freedom; momenta conjugate to "
              + ", ".join(ch.names[:ch.n]))
    for name, x, kind in zip(ch.names[ch.n:], ch.x0[ch.n:], ch.kinds):
        print(f"{name:>24}  {x:+.12g} {units[kind]}")
    try:
        print(f"{'H':>24}  {hamiltonian(m):+.12g} J")
    except ConfigError as e:
        print(f"{'H':>24}  - ({e})")
    print(f"{'integrator':>14}  {'h (s)':>9}  {'|M^T J M - J|':>13}  {'floor':>9}  verdict")
    for integ in integrators:
        for h in steps:
            try:
                r = symplecticity_error(m, integ, h)
            except ConfigError as e:
                if args.integrator:
                    raise
                print(f"{integ:>14}  {h:>9.3g}  {'-':>13}  {'-':>9}  does not apply: {e}")
                break
            verdict = ("not smooth: no measurement" if not r.smooth else
                       "within the floor (symplectic as far as it shows)" if r.at_floor else "not symplectic")
            if r.note:
                verdict += f"; {r.note}"
            print(f"{integ:>14}  {h:>9.3g}  {r.error:>13.3e}  {r.floor:>9.2e}  {verdict}")
    return 0
