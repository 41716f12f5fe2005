"""The service tests' own helpers: waiting for a log line of a subprocess must see every line that came, however
late the test process wakes up, and a wait that runs out must say where the process was."""

import subprocess
import sys
import time

import pytest
import svc_helpers
from svc_helpers import endpoint, free_port, reap, start, stop, wait_for_line  # noqa: F401 - reap: autouse


def _writer(text: str) -> subprocess.Popen:
    """A process that writes ``text`` to stderr in one write (so it all sits in the pipe at once) and sleeps."""
    code = f"import os, time; os.write(2, {text.encode()!r}); time.sleep(60)"
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    svc_helpers._STARTED.append(p)  # killed by the reap fixture
    return p


def test_wait_for_line_sees_a_line_that_came_with_the_one_before():
    """`gyrosim serve` logs "serving scene" and "stepping" 10 ms apart: a loaded machine wakes the reader after
    both are in the pipe. Reading through the Popen's text wrapper buffered the second line where `select` cannot
    see it, and the wait ran out (90 s) with the serve stepping all along; the wait must return at once."""
    p = _writer("gyrosim serve: serving scene 'gyroscope'\ngyrosim serve: stepping: h = 0.01 s\nafter\n")
    t0 = time.monotonic()
    lines = wait_for_line(p, "stepping", timeout=20)
    assert time.monotonic() - t0 < 10
    assert lines == ["gyrosim serve: serving scene 'gyroscope'\n", "gyrosim serve: stepping: h = 0.01 s\n"]
    p.kill()
    _, err = p.communicate(timeout=10)
    assert err == "after\n"  # what follows the needle's line stays for communicate()


def test_wait_for_line_that_never_comes_ends_with_the_process_stacks():
    """A wait that runs out on a running service command includes its stacks (faulthandler on SIGUSR1)."""
    srv = start("serve", "gyroscope", "-l", endpoint(free_port()), "--wall-duration", 600)
    wait_for_line(srv, "stepping")
    with pytest.raises(AssertionError) as e:
        wait_for_line(srv, "a line never logged", timeout=0.5)
    text = str(e.value)
    assert "still running" in text and "most recent call first" in text and "serve.py" in text, text
    code, out, err = stop(srv)  # SIGUSR1 did not stop it: SIGINT does, cleanly
    assert code == 0 and "stopped by SIGINT" in out, err


def test_wait_for_line_stops_at_once_when_the_process_ends():
    p = _writer("only line\n")
    p.kill()
    t0 = time.monotonic()
    with pytest.raises(AssertionError, match="exited"):
        wait_for_line(p, "never", timeout=30)
    assert time.monotonic() - t0 < 10
