# gyrosim: `make demo` and `make test` set everything up on a machine with only Python 3.11+.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test bench docs lint clean venv

ENGINE := $(wildcard src/gyrosim/core/engine/*) src/gyrosim/core/_enginemodule.c setup.py

# the C engine is compiled at install: a changed source reinstalls
$(STAMP): pyproject.toml $(ENGINE)
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

venv: $(STAMP)

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests bench

# two workers (pytest-xdist): the CI machine's two cores; every test keeps to its own temporary folder and ports
test: $(STAMP) lint
	$(PY) -m pytest -q -n 2

demo: $(STAMP)
	$(PY) -m gyrosim.demo

BENCH_VENV := .venv-bench

$(BENCH_VENV)/.installed: pyproject.toml $(ENGINE)
	$(PYTHON) -m venv $(BENCH_VENV)
	$(BENCH_VENV)/bin/python -m pip install --quiet --upgrade pip
	$(BENCH_VENV)/bin/python -m pip install --quiet -e ".[test,bench]"
	touch $(BENCH_VENV)/.installed

# the slow tests in the project's venv; the study in .venv-bench (with the benchmark-only peers: CyRK, numba;
# numba's cache inside the bench venv, never next to the sources)
bench: $(STAMP) $(BENCH_VENV)/.installed
	$(PY) -m pytest -q -m slow
	NUMBA_CACHE_DIR=$(CURDIR)/$(BENCH_VENV)/numba-cache $(BENCH_VENV)/bin/gyrosim bench --output docs/study

# the documentation site into site/ (git-ignored), warnings as errors; the study's tables and plots in docs/study
# come from `make bench`
DOCS_STAMP := $(VENV)/.docs-installed

$(DOCS_STAMP): $(STAMP)
	$(PY) -m pip install --quiet -e ".[test,docs]"
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)
	$(VENV)/bin/mkdocs build --strict --site-dir site

clean:
	rm -rf $(VENV) $(BENCH_VENV) .pytest_cache fmu/dist out build site src/gyrosim/core/*.so
