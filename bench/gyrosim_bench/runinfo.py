"""What a bench run records about where it ran: the machine, the load averages and which gyrosim (commit, local
changes to src, when the engine was built). One piece for the benches that write an ``environment`` block
(contact_bench, iftomm_bench); imported by their parent process only (their peer workers run as scripts)."""

from __future__ import annotations

import os
import subprocess
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]   # the checkout


def load() -> str:
    """The 1, 5 and 15 minute load averages (other processes on the machine share its cores)."""
    try:
        return " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        return "?"


def environment(command: str) -> dict:
    """The command, the CPU and its count, Python, the time, the load at the start and :func:`gyrosim_state`."""
    import platform

    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    return {"command": command, "machine": f"{cpu}, {os.cpu_count()} CPUs",
            "python": f"Python {platform.python_version()}", "when": time.strftime("%Y-%m-%d %H:%M:%S"),
            "load_start": load(), "gyrosim": gyrosim_state()}


def gyrosim_state() -> str:
    """Which gyrosim ran: the package's version, the checkout's commit, whether its src differs from it (and a hash
    of the difference) and when the engine was built."""
    import hashlib

    import gyrosim

    out = f"gyrosim {getattr(gyrosim, '__version__', '?')}"
    try:
        head = subprocess.run(["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"], capture_output=True,
                              text=True, timeout=30).stdout.strip()
        diff = subprocess.run(["git", "-C", str(ROOT), "diff", "HEAD", "--", "src"], capture_output=True,
                              timeout=30).stdout
        if head:
            out += f", commit {head}" + (f" with uncommitted changes to src (diff sha1 "
                                         f"{hashlib.sha1(diff).hexdigest()[:10]})" if diff else "")
    except (OSError, subprocess.TimeoutExpired):
        pass
    try:
        from gyrosim.core import _engine

        built = time.localtime(os.path.getmtime(_engine.__file__))
        out += ", engine built " + time.strftime("%Y-%m-%d %H:%M:%S", built)
    except Exception:  # noqa: BLE001 - the rest of the line without it
        pass
    return out
