# Two entry points, each sets up .venv on first use:
#   make demo   - run the main job on the simulated rig
#   make test   - lint and run the whole test suite
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# test processes: three for every two cores (pytest-xdist); a file's tests stay in one process
# so its module fixtures (a whole simulated calibration) run once. Many tests wait on the wall
# clock (paced simulated rigs, windows, servers), so one process per core left a core idle;
# three per two cores keep both busy (docs/architecture.md). TEST_WORKERS=0 runs serially.
TEST_WORKERS ?= $(shell echo $$(( $$(nproc 2>/dev/null || echo 1) * 3 / 2 )))

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
