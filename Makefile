# gyrosim: `make demo` and `make test` set everything up on a machine with only Python 3.11+.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
export NUMBA_CACHE_DIR ?= $(CURDIR)/.numba_cache

.PHONY: demo test test-nojit bench docs lint clean venv

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $(STAMP)

venv: $(STAMP)

lint: $(STAMP)
	$(VENV)/bin/ruff check src tests

test: $(STAMP) lint
	$(PY) -m pytest -q
	NUMBA_DISABLE_JIT=1 $(PY) -m pytest -q -m "nojit and not slow" -p no:cacheprovider

test-nojit: $(STAMP)
	NUMBA_DISABLE_JIT=1 $(PY) -m pytest -q -m "nojit and not slow"

demo: $(STAMP)
	$(PY) -m gyrosim.demo

bench: $(STAMP)
	$(PY) -m pytest -q -m slow
	$(VENV)/bin/gyrosim bench --output docs/study

docs: $(STAMP)
	$(VENV)/bin/gyrosim bench --output docs/study

clean:
	rm -rf $(VENV) .numba_cache .pytest_cache fmu/dist out
