"""The tree engine's rk4 step cost against the number of bodies: chains of hinges and random trees of 10, 30, 100,
300 and 1,000 bodies (issue 35: trees of any size in O(n) per step).

Each tree is driven from Python through ``_engine.tree_advance`` with many rk4 steps in one call (the call's own
cost spread over them), the best of a few repetitions. The per-body cost (ns per step per body) stays roughly
constant where the cost grows linearly. Trees of up to 32 bodies run the engine's small build (fixed arrays),
larger ones its large build (tables sized by the tree: engine/tree_big.c).

Run from the source checkout::

    PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.tree_scaling --output docs/study [--quick]

or ``gyrosim bench --only tree_scaling``. Writes ``tree_scaling.md``, ``tree_scaling.json`` and ``tree_scaling.png``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from .ticks import tidy_log_ticks

__all__ = ["main", "run"]

SIZES = (10, 30, 100, 300, 1000)
H = 1e-4


def _inertia(rng, mass):
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                  [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                  [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
    return R @ np.diag(rng.uniform(1.0, 3.0, 3) * 1e-2 * mass) @ R.T


def tree(kind: str, n: int, seed: int = 0):
    """(desc, y, p) of a chain of hinges ("chain") or a random tree ("random": every parent uniform among the
    earlier bodies; hinge, ball, free_rotation and fixed joints), gravity on, small random rates."""
    from gyrosim.core.tree import TreeBody, TreeLayout

    rng = np.random.default_rng(seed)
    bodies = []
    for i in range(n):
        if kind == "chain":
            parent, joint = i - 1, "hinge"
        else:
            parent = -1 if i == 0 else int(rng.integers(0, i))
            joint = "ball" if i == 0 else str(rng.choice(["hinge", "ball", "free_rotation", "fixed"],
                                                         p=[0.45, 0.25, 0.15, 0.15]))
        mass = float(rng.uniform(0.5, 2.0))
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        pos = np.array([0.0, 0.0, -0.1 if i else 0.0]) + rng.uniform(-0.02, 0.02, 3)
        kw = dict(name=f"b{i}", parent=parent, joint=joint, pos=pos,
                  axis=axis, mass=mass, cm=np.zeros(3) if joint == "free_rotation" else rng.uniform(-0.05, 0.05, 3),
                  inertia=_inertia(rng, mass))
        if joint in ("ball", "free_rotation"):
            q = rng.normal(size=4)
            kw.update(q0=q / np.linalg.norm(q), omega0=rng.uniform(-0.5, 0.5, 3))
        elif joint == "hinge":
            kw.update(angle0=float(rng.uniform(-1, 1)), rate0=float(rng.uniform(-0.5, 0.5)))
        bodies.append(TreeBody(**kw))
    lay = TreeLayout(bodies, ())
    return lay, lay.state(), lay.params(9.81, 0.0)


def step_ns(lay, y0, p, steps: int, reps: int) -> float:
    """ns per rk4 step: the best of reps calls of `steps` steps each."""
    from gyrosim.core import _engine

    P = p[None, :].copy()
    P[0, _engine.TP_DRIFT] = 0.0
    rk4 = _engine.METHODS.index("rk4")
    best = float("inf")
    for _ in range(reps):
        y = y0[None, :].copy()
        _engine.tree_start(lay.desc, y, P)
        hint, stats, status = np.zeros(1), np.zeros((1, 3), dtype=np.int64), np.zeros(1, dtype=np.int32)
        t0 = time.perf_counter()
        failed = _engine.tree_advance(lay.desc, rk4, y, P, steps * H, 0.0, 0.0, H, hint, stats, status, 1)
        dt = time.perf_counter() - t0
        if failed:
            raise RuntimeError(f"the run failed (status {status[0]})")
        best = min(best, dt / steps * 1e9)
    return best


def _plot(rows, png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(1, 2, figsize=(10, 4))
    for kind, mk in (("chain", "o-"), ("random", "s-")):
        r = [x for x in rows if x["tree"] == kind]
        n = [x["bodies"] for x in r]
        ax[0].loglog(n, [x["ns_per_step"] for x in r], mk, label=f"{kind}")
        ax[1].semilogx(n, [x["ns_per_step_per_body"] for x in r], mk, label=f"{kind}")
    nn = np.array([10, 1000])
    ref = [x for x in rows if x["tree"] == "chain"][0]
    ax[0].loglog(nn, ref["ns_per_step"] * nn / ref["bodies"], "k:", label="linear")
    ax[0].set(xlabel="bodies", ylabel="ns per rk4 step", title="rk4 step cost")
    ax[1].set(xlabel="bodies", ylabel="ns per rk4 step per body", title="per body (flat: O(n))")
    ax[1].set_ylim(bottom=0)
    for a in ax:
        a.grid(True, which="both", alpha=0.3)
        a.legend()
    ax[1].axvline(32.5, color="gray", lw=0.8)
    ax[1].text(34, ax[1].get_ylim()[1] * 0.05, "large build (> 32)", fontsize=8, color="gray")
    fig.tight_layout()
    tidy_log_ticks(fig)
    fig.savefig(png, dpi=110)
    plt.close(fig)


def run(out_dir, quick: bool = False) -> list[dict]:
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rows = []
    for kind in ("chain", "random"):
        for n in SIZES:
            lay, y, p = tree(kind, n)
            steps = max(20, int((2e5 if quick else 2e6) / n))
            ns = step_ns(lay, y, p, steps, 2 if quick else 5)
            rows.append({"tree": kind, "bodies": n, "dof": lay.dof, "steps": steps, "ns_per_step": round(ns, 1),
                         "ns_per_step_per_body": round(ns / n, 1)})
            print(f"{kind:7s} {n:5d} bodies: {ns:12.1f} ns/step  {ns / n:8.1f} ns/step/body", flush=True)
    cmd = "PYTHONPATH=bench .venv/bin/python -m gyrosim_bench.tree_scaling --output docs/study"
    lines = ["# Tree engine: rk4 step cost against the number of bodies", "",
             f"`{cmd}` ({platform.machine()}, {platform.python_version()}; rk4, h = {H:g} s, many steps in one "
             "`_engine.tree_advance` call, the best of several). Chains of hinges; random trees with hinge, ball, "
             "free_rotation and fixed joints. Up to 32 bodies: the engine's small build (fixed arrays); beyond: "
             "its large build (tables sized by the tree).", "",
             "| tree | bodies | dof | ns per step | ns per step per body |", "|---|---:|---:|---:|---:|"]
    for r in rows:
        lines.append(f"| {r['tree']} | {r['bodies']} | {r['dof']} | {r['ns_per_step']:.0f} | "
                     f"{r['ns_per_step_per_body']:.0f} |")
    lines += ["", "![rk4 step cost](tree_scaling.png)", ""]
    (out / "tree_scaling.md").write_text("\n".join(lines))
    (out / "tree_scaling.json").write_text(json.dumps(rows, indent=1))
    _plot(rows, out / "tree_scaling.png")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--output", default="docs/study")
    ap.add_argument("--quick", action="store_true")
    a = ap.parse_args(argv)
    run(a.output, a.quick)


if __name__ == "__main__":
    main()
