"""The documentation's code runs: every Python block of README.md and docs/*.md, the docstring examples of the
modules the API pages show, and (when mkdocs is installed) the site builds with --strict.

A block is skipped only when the line before its fence says so: ``<!-- docs-test: skip REASON -->``. The line
``<!-- docs-test: setup gyrosim ARGS -->`` runs ``gyrosim ARGS`` first (e.g. the shell command whose output the
block reads). Blocks of one page run in order in one namespace, in a fresh folder.
"""

from __future__ import annotations

import doctest
import importlib
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^(?P<marker><!-- docs-test: (?P<kind>skip|setup)\b(?P<arg>.*?)-->\n)?"
                   r"```python[^\n]*\n(?P<code>.*?)^```", re.S | re.M)

#: Blocks in pages this suite does not own the text of, run elsewhere or needing what a test cannot have here.
#: (page name, a line of the block) -> why; a marker in the page does the same.
ELSEWHERE = {
    ("service.md", 'with open("run.mcap", "rb") as f:'): "reads the recording of `gyrosim serve --record run.mcap`",
    ("service.md", "import zenoh"): "needs a running service: tests/service/test_service_docs.py runs it against one",
}


def blocks(page: Path):
    """``(line, code, skip_reason or None, setup argv or None)`` for every Python block of ``page``."""
    text = page.read_text()
    out = []
    for m in FENCE.finditer(text):
        line = text.count("\n", 0, m.start("code")) + 1
        code = m.group("code")
        skip = m.group("arg").strip() if m.group("kind") == "skip" else None
        for (name, needle), why in ELSEWHERE.items():
            if page.name == name and needle in code:
                skip = why
        setup = shlex.split(m.group("arg")) if m.group("kind") == "setup" else None
        out.append((line, code, skip, setup))
    return out


def test_the_pages_have_python_blocks_and_the_markers_are_known():
    counts = {p.name: len(blocks(p)) for p in PAGES}
    assert counts["README.md"] >= 2 and counts["index.md"] >= 2 and counts["model-api.md"] == 1
    for page in PAGES:
        for marker in re.findall(r"<!-- docs-test:(.*?)-->", page.read_text()):
            assert marker.split()[0] in ("skip", "setup"), (page.name, marker)
        for line, _code, skip, setup in blocks(page):
            assert skip is None or skip, f"{page.name}:{line}: a skip needs a reason"
            assert setup is None or setup[0] == "gyrosim", f"{page.name}:{line}: setup runs a gyrosim command"


@pytest.mark.parametrize("page", [p for p in PAGES if blocks(p)], ids=lambda p: p.name)
def test_every_python_block_runs(page, tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from gyrosim.cli import main

    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": f"docs_{page.stem}"}
    ran = 0
    for line, code, skip, setup in blocks(page):
        if skip:
            continue
        if setup:
            assert main(setup[1:]) == 0, f"{page.name}:{line}: setup {' '.join(setup)} failed"
        # compiled with the page's name and line numbers, so a failure points at the documentation
        exec(compile("\n" * (line - 1) + code, str(page), "exec"), namespace)  # noqa: S102 - the docs' own code
        ran += 1
    assert ran or all(skip for _, _, skip, _ in blocks(page))


#: Modules whose docstrings the API pages show: their examples run as doctests.
DOCTEST_MODULES = ["gyrosim.trajectory", "gyrosim.model", "gyrosim.core.inertia", "gyrosim.core.seeds",
                   "gyrosim.core.analytic", "gyrosim.scene", "gyrosim.analysis.linear", "gyrosim.analysis.hamilton"]


@pytest.mark.parametrize("name", DOCTEST_MODULES)
def test_docstring_examples_run(name):
    mod = importlib.import_module(name)
    finder = doctest.DocTestFinder(exclude_empty=True)
    runner = doctest.DocTestRunner(optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    for test in finder.find(mod, name, globs=dict(vars(mod))):
        runner.run(test)
    result = runner.summarize(verbose=False)
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (output above)"


@pytest.mark.skipif(shutil.which("mkdocs", path=str(Path(sys.executable).parent)) is None,
                    reason="mkdocs is not installed (make docs installs the docs extra)")
def test_the_site_builds_strictly(tmp_path):
    exe = Path(sys.executable).parent / "mkdocs"
    r = subprocess.run([str(exe), "build", "--strict", "--site-dir", str(tmp_path / "site")], cwd=ROOT,
                       capture_output=True, text=True, timeout=120, env={"NO_MKDOCS_2_WARNING": "1",
                                                                         "PATH": "/usr/bin:/bin"})
    assert r.returncode == 0, r.stderr
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    for name in ("simulate", "InertiaTensor", "from_products", "Model", "load_scene"):
        assert name in api
