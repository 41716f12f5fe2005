"""docs/service.md quotes code that runs: the consumer snippet against a live service."""

import re
from pathlib import Path

from test_service_inputs import Served

DOC = Path(__file__).resolve().parents[2] / "docs" / "service.md"


def _snippet(after: str) -> str:
    text = DOC.read_text()
    section = text[text.index(after):]
    return re.search(r"```python\n(.*?)```", section, re.S).group(1)


def test_the_consumer_snippet_runs_against_a_live_service(capsys):
    code = _snippet("## Consuming the stream from another process")
    with Served("gyroscope", rate=200.0) as s:
        exec(compile(code, str(DOC), "exec"), {"ENDPOINT": f"tcp/127.0.0.1:{s.port}", "N": 20})
    t, seq, omega_z, integrator = capsys.readouterr().out.split()
    assert int(seq) >= 19 and float(omega_z) > 100 and integrator == "splitting"
