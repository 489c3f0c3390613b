# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: one per core (pytest-xdist); a file's tests stay in one process so its
# module fixtures (a whole simulated calibration) run once. Two per core were faster but
# starved the paced wire-level rigs once the sweep tests' Dask processes ran beside them
# (docs/architecture.md). TEST_WORKERS=0 runs serially.
TEST_WORKERS ?= $(shell nproc 2>/dev/null || echo 1)

.PHONY: demo test bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/rotorbench demo

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) .pytest_cache
