# davinci-sim: every target does its own set-up.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
export MUJOCO_GL ?= egl

.PHONY: install system-deps run test lint bench clean

# Debian packages for headless OpenGL (EGL on Mesa's llvmpipe). Installed only if missing.
system-deps:
	@bash scripts/system-deps.sh

# three.js (the page draws the endoscope with it) is fetched from the npm registry and
# checked against its pinned SHA-512 by davinci_sim.web.vendor, into the virtual environment.
$(STAMP): pyproject.toml scripts/system-deps.sh src/davinci_sim/web/vendor.py
	@$(MAKE) --no-print-directory system-deps
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	$(BIN)/python -m davinci_sim.web.vendor
	@touch $(STAMP)

install: $(STAMP)

# The web console with the seed's task: open the printed URL in a browser. The loop process
# asks for real-time priority (granted to root or with CAP_SYS_NICE; else normal priority).
# The numba kernels compile on every core first (davinci_sim.warm_up: on a fresh clone about
# two and a half minutes, 2026-12-03; afterwards it finds them cached in a few seconds).
run: install
	@$(BIN)/python -m davinci_sim.warm_up || true
	$(BIN)/davinci-sim serve --task seed_path --home --realtime-priority 50

lint: install
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/mypy

# The linters run while the numba kernels compile into their cache on every core
# (davinci_sim.warm_up: a speed-up only, pytest's controller warms up again if it failed);
# then two pytest-xdist workers, whole test modules each
# (tests/conftest.py: the browser modules are one unit, run first). Plain `pytest` (no -n)
# runs the same tests in one process.
test: install
	@$(BIN)/python -m davinci_sim.warm_up & warm=$$!; \
	$(MAKE) --no-print-directory lint; lint=$$?; wait $$warm; exit $$lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=30

bench: install
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) build dist .pytest_cache
