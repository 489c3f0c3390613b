# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: one per core (pytest-xdist). A file's tests stay in one process so its
# module fixtures (a whole simulated calibration) run once. Three per two cores
# (TEST_WORKERS=3 here) are faster, 4 min 43 s - 4 min 58 s from a fresh clone on a quiet
# machine, but one of thirteen such runs tripped the host watchdog of a calibration over
# TCP (its command loop starved 1.7 s): docs/architecture.md. TEST_WORKERS=0 runs serially.
TEST_WORKERS ?= $(shell nproc 2>/dev/null || echo 1)

.PHONY: demo test bench lint clean

# The venv: uv installs what pip would, in half the time (bytecode compiled too); pip is the
# fallback where uv cannot be installed or cannot reach the package index.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	( $(BIN)/python -m pip install --quiet uv && \
	  $(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -e '.[dev]' ) || \
	  ( $(BIN)/python -m pip install --quiet --upgrade pip && \
	    $(BIN)/python -m pip install --quiet -e '.[dev]' )
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/rotorbench demo

# The project's own bytecode, written once: with PYTHONDONTWRITEBYTECODE set (CI, many
# containers) every process of the suite (three test processes, dozens of `rotorbench`
# subprocesses, Dask workers, windows) compiled the packages from source again.
test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/python -m compileall -q -j0 bench drivers analysis optimizer > /dev/null
	QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) .pytest_cache
