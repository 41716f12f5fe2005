"""An FMU of a tree beyond the small build's 32 bodies (engine/tree_big.c): a chain of 200 hinged links, built for
FMI 2.0 and 3.0, run by FMPy in co-simulation to gyrosim.simulate's bits; and (slow: ``pytest -m slow``) valgrind
over the big build's arena in a Python process: no invalid access and no definite leak from the engine."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

import gyrosim
from gyrosim.core.tree import BODY_OUTPUTS
from gyrosim.fmu import build_fmu
from gyrosim.kernel_tree import tree_output_names
from gyrosim.scene import load_scene

DYADIC = 2.0 ** -7


def chain_toml(n: int) -> str:
    """n point masses on light links hinged about y, each 0.1 m below the last, released from a bent shape."""
    head = ('[scene]\nname = "long_chain"\ndescription = "a chain of hinged links"\nintegrator = "rk4"\n'
            'max_step = 0.001\ng = 9.81\n')
    links = []
    for i in range(n):
        parent = "world" if i == 0 else f"l{i - 1}"
        z = 0.0 if i == 0 else -0.1
        links.append(f'[[body]]\nname = "l{i}"\nparent = "{parent}"\njoint = "hinge"\nposition = [0.0, 0.0, {z}]\n'
                     f'axis = [0.0, 1.0, 0.0]\nmass = 0.1\ncm = [0.0, 0.0, -0.1]\n'
                     f'inertia = {{ principal = [1e-5, 1e-5, 1e-6] }}\nangle = {0.3 if i % 7 == 0 else 0.0}\n')
    return head + "\n".join(links)


@pytest.mark.parametrize("v", (2, 3))
def test_a_200_link_chain_fmu_runs_to_the_models_bits(tmp_path, v):
    toml = tmp_path / "chain.toml"
    toml.write_text(chain_toml(200))
    names = tree_output_names(load_scene(str(toml)))
    assert len(names) == 200 * (2 + len(BODY_OUTPUTS)) + 5
    ref = gyrosim.simulate(str(toml), stop_time=12 * DYADIC, output_interval=DYADIC)
    path = build_fmu(str(toml), v, tmp_path / f"fmi{v}", windows=False)
    assert len(read_model_description(str(path)).modelVariables) > 1200
    r = simulate_fmu(str(path), stop_time=12 * DYADIC, output_interval=DYADIC, output=names)
    for n in names:
        assert np.array_equal(r[n], ref[n]), n
    # rk4 at 1 ms on the chain's fast modes (0.1 kg links): its truncation error, 1e-8 of the energy
    assert np.abs(r["energy_error"]).max() < 1e-6 * np.abs(r["energy"]).max()


VALGRIND = """
import numpy as np, sys
from gyrosim import Model
from gyrosim.scene import load_scene
sc = load_scene(sys.argv[1])
for k in range(3):
    m = Model(sc)
    m.step(0.005)
    m.set("integrator", "dop853")
    m.step(0.002)
    m.linearize()
print("done")
"""


@pytest.mark.slow
def test_no_memory_error_in_the_big_build(tmp_path):
    """valgrind memcheck over a Python process that runs a 40-link chain (the big build) with rk4, dop853 and the
    complex-step linearization three times: no invalid access or uninitialised value at the engine's frames and no
    definite leak allocated by it."""
    if shutil.which("valgrind") is None:
        pytest.skip("valgrind is not installed")
    toml = tmp_path / "chain.toml"
    toml.write_text(chain_toml(40))
    script = tmp_path / "run.py"
    script.write_text(VALGRIND)
    log = tmp_path / "valgrind.log"
    p = subprocess.run(["valgrind", "--error-limit=no", "--num-callers=30", "--leak-check=full", f"--log-file={log}",
                        sys.executable, str(script), str(toml)], capture_output=True, text=True, timeout=3000)
    assert p.returncode == 0 and "done" in p.stdout, p.stderr[-2000:]
    bad = []
    for block in log.read_text().split("\n==") if log.exists() else []:
        frames = re.findall(r"(?:at|by) 0x[0-9A-F]+: .*", block)
        engine = [f for f in frames[:3] if "_engine" in f]
        if re.search(r"Invalid (read|write)|uninitialised", block) and engine:
            bad.append(block)
        if "definitely lost" in block and any("_engine" in f for f in frames[1:4]):
            bad.append(block)
    assert not bad, "\n".join(bad[:3])
