# Two commands: `make demo` and `make test`. Both create .venv at the repository root if missing.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
OUT ?= out

.PHONY: demo test test-all docs bench clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Stamp files so that the install re-runs when pyproject.toml changes. pip installs without byte-compiling and
# compileall then compiles the environment and the package on every core (pip compiles on one: 15 s of the setup).
$(VENV)/.installed: pyproject.toml | $(BIN)/python
	@echo "make: installing pmaccuracy and its dependencies into $(VENV) (first run: a minute or two)"
	$(BIN)/python -m pip install --quiet --no-compile -e ".[all]"
	$(BIN)/python -m compileall -q -j 0 $(VENV)/lib src > /dev/null || true
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	@echo "make: installing pmaccuracy, its dependencies and the test tools into $(VENV) (first run: a minute or two)"
	$(BIN)/python -m pip install --quiet --no-compile -e ".[all,test]"
	$(BIN)/python -m compileall -q -j 0 $(VENV)/lib src > /dev/null || true
	touch $@ $(VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/pmaccuracy reproduce --out $(OUT)

# The CI suite on every core (at most 4 workers), without the tests marked slow (longer sweeps of claims that
# faster tests also check); `make test-all` runs every test.
test: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4 -m "not slow"

test-all: $(VENV)/.installed-test
	$(BIN)/python -m pytest -q -n auto --maxprocesses=4

$(VENV)/.installed-docs: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e ".[all,docs]"
	touch $@

# The documentation site (the guide pages of docs/guide/ and API pages from the docstrings), offline, warnings as errors.
docs: $(VENV)/.installed-docs
	rm -rf docs/generated docs/_build
	$(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html
	@echo "docs: docs/_build/html/index.html"

bench: $(VENV)/.installed-test
	$(BIN)/python benchmarks/bench_floor.py
	$(BIN)/python benchmarks/bench_public.py
	$(BIN)/python benchmarks/bench_first_call.py
	$(BIN)/python benchmarks/bench_bounds.py
	$(BIN)/python benchmarks/bench_maps.py
	$(BIN)/python benchmarks/bench_scale.py
	$(BIN)/python benchmarks/bench_calibration.py
	$(BIN)/python benchmarks/bench_spatial_kinematics.py --first-call
	$(BIN)/python benchmarks/bench_assembly_modes.py
	$(BIN)/python benchmarks/bench_support.py
	$(BIN)/python benchmarks/bench_spatial_bounds.py
	$(BIN)/python benchmarks/bench_spatial_worst.py
	$(BIN)/python benchmarks/bench_spatial_calibration.py

clean:
	rm -rf $(VENV) $(OUT) build src/*.egg-info .pytest_cache docs/_build docs/generated
