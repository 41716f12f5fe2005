"""A logger for FMPy's low-level instances, shared by the FMU tests."""


def text(x) -> str:
    """A C string from FMPy (bytes or str or None) as str."""
    return x.decode() if isinstance(x, bytes) else (x or "")


class FmiLog:
    """Keeps (status, category, message) of every logged message."""

    def __init__(self):
        self.messages = []

    def __call__(self, *args):
        # FMI 2.0: (env, instanceName, status, category, message); FMI 3.0: (env, status, category, message)
        status, category, message = args[-3:]
        self.messages.append((int(status), text(category), text(message)))

    def errors(self) -> list[str]:
        """Messages logged with status Error or worse."""
        return [m for s, _, m in self.messages if s >= 3]

    def clear(self):
        self.messages.clear()


def expect_error(call, log: FmiLog, *words) -> str:
    """``call()`` raises FMPy's FMICallException with status Error (3) (never Fatal), and each of ``words`` is in
    an Error message that reached ``log`` during the call; returns the text of those messages."""
    import pytest
    from fmpy.fmi1 import FMICallException

    log.clear()
    with pytest.raises(FMICallException) as e:
        call()
    assert e.value.status == 3, f"status {e.value.status}, expected Error (3)"
    errors = log.errors()
    assert errors, "no Error message reached the logger"
    for w in words:
        assert any(w in m for m in errors), f"{w!r} in none of {errors!r}"
    return " ".join(errors)
