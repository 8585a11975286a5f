# Two commands: `make demo` and `make test`. Both create .venv at the repository root if missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= out

.PHONY: demo test test-all bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Stamp files so that the install re-runs when pyproject.toml changes.
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $@ $(VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/pmaccuracy reproduce --out $(OUT)

# The CI suite on every core (at most 4 workers), without the tests marked slow (longer sweeps of claims that
# faster tests also check); `make test-all` runs every test. Times: README "Tests".
test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4 -m "not slow"

test-all: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4

bench: $(VENV)/.installed-test
	$(BIN)/python benchmarks/bench_floor.py
	$(BIN)/python benchmarks/bench_bounds.py
	$(BIN)/python benchmarks/bench_maps.py
	$(BIN)/python benchmarks/bench_scale.py

clean:
	rm -rf $(VENV) $(OUT) build src/*.egg-info .pytest_cache
