# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: three per two cores (pytest-xdist): many tests wait on the wall clock
# (paced wire rigs, windows, server outages), so one per core leaves the cores idle about a
# third of the time. A file's tests stay in one process so its module fixtures (a whole
# simulated calibration) run once. TEST_WORKERS=0 runs serially. docs/architecture.md.
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 1); echo $$((n + n / 2)))

.PHONY: demo test bench lint clean

# The venv: uv installs what pip would, in half the time; pip is the fallback where uv
# cannot be installed or cannot reach the package index. Bytecode is written on first import
# (below), not for all 15000 files of the venv at install (19 s here; the suite uses 2700).
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	( $(BIN)/python -m pip install --quiet uv && \
	  $(BIN)/uv pip install --quiet --python $(BIN)/python -e '.[dev]' ) || \
	  ( $(BIN)/python -m pip install --quiet --upgrade pip && \
	    $(BIN)/python -m pip install --quiet -e '.[dev]' )
	touch $(STAMP)

# PYTHONDONTWRITEBYTECODE= : Python writes the bytecode of what it imports, once, even where
# the environment says not to (CI, many containers): otherwise every process of the suite
# (test processes, dozens of `rotorbench` subprocesses, Dask workers, windows) compiled each
# module it imports from source again. It is written into .venv and the source tree only.
demo: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/rotorbench demo

test: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/basedpyright --project pyproject.toml --pythonpath $(BIN)/python
	PYTHONDONTWRITEBYTECODE= QT_QPA_PLATFORM=offscreen $(BIN)/python -m pytest -q \
	  -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder --durations=30

bench: $(STAMP)
	$(BIN)/python benchmarks/run_all.py

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/basedpyright --project pyproject.toml --pythonpath $(BIN)/python

clean:
	rm -rf $(VENV) .pytest_cache
