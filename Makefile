# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: three per two cores (pytest-xdist; at least two). Many tests wait on the
# wall clock (the paced wire-level rigs, the windows, the lab servers' outages), so with one
# process per core a core sat idle through those waits. A file's tests stay in one process
# so its module fixtures (a whole simulated calibration) run once. TEST_WORKERS=0 runs
# serially. docs/architecture.md has the measurements.
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$(( (3 * n + 1) / 2 )))

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
