# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: one per core (pytest-xdist); a file's tests stay in one process so its
# module fixtures (a whole simulated calibration) run once. Three per two cores were faster
# (4 min 39 s - 5 min 23 s from a fresh clone against about 6) but starved the paced
# wire-level rigs on two busy cores: two load failures and a hang in seven fresh-clone runs
# (docs/architecture.md). TEST_WORKERS=0 runs serially.
TEST_WORKERS ?= $(shell nproc 2>/dev/null || echo 1)

.PHONY: demo test bench lint clean

# The venv: uv installs what pip would, in half the time (bytecode compiled too); pip is the
# fallback where uv cannot be installed or cannot reach the package index.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	( $(BIN)/python -m pip install --quiet uv && \
	  $(BIN)/uv pip install --quiet --compile-bytecode --python $(BIN)/python -e '.[dev]' ) || \
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
