# davinci-sim: every target does its own set-up.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DEV_STAMP := $(VENV)/.installed-dev
export MUJOCO_GL ?= egl

.PHONY: install install-dev system-deps run test lint bench clean

# Debian packages for headless OpenGL (EGL on Mesa's llvmpipe). Installed only if missing.
system-deps:
	@bash scripts/system-deps.sh

# What the simulator needs to run (`make run`); three.js (the page draws the endoscope with
# it) is fetched from the npm registry and checked against its pinned SHA-512 by
# davinci_sim.web.vendor, into the virtual environment.
$(STAMP): pyproject.toml scripts/system-deps.sh src/davinci_sim/web/vendor.py
	@$(MAKE) --no-print-directory system-deps
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	$(BIN)/python -m davinci_sim.web.vendor
	@touch $(STAMP)

# The developers' tools on top (pytest, the linters, Playwright, Ray: about as long again to
# install, 2026-12-03: 37 s after 38 s), for test, lint and bench; `make run` does without.
# The `dev` extra's requirements by name, so that the installed package is left as it is
# (`make test` runs this while the kernels compile from it).
$(DEV_STAMP): $(STAMP)
	$(BIN)/python -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', \
	'rb'))['project']['optional-dependencies']['dev']))" > $(VENV)/dev-requirements.txt
	$(BIN)/python -m pip install --quiet -r $(VENV)/dev-requirements.txt
	@touch $(DEV_STAMP)

install: $(STAMP)

install-dev: $(DEV_STAMP)

# The web console with the seed's task: open the printed URL in a browser. The loop process
# asks for real-time priority (granted to root or with CAP_SYS_NICE; else normal priority).
# The numba kernels compile on every core first (davinci_sim.warm_up: on a fresh clone about
# two minutes, 2026-12-03; afterwards it finds them cached in a few seconds).
run: install
	@$(BIN)/python -m davinci_sim.warm_up || true
	$(BIN)/davinci-sim serve --task seed_path --home --realtime-priority 50

lint: install-dev
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/mypy

# The developers' tools install and the linters run while the numba kernels compile into
# their cache on every core
# (davinci_sim.warm_up: a speed-up only, pytest's controller warms up again if it failed);
# then two pytest-xdist workers, whole test modules each
# (tests/conftest.py: the browser modules are one unit, run first). Plain `pytest` (no -n)
# runs the same tests in one process.
test: install
	@$(BIN)/python -m davinci_sim.warm_up & warm=$$!; \
	$(MAKE) --no-print-directory lint; lint=$$?; wait $$warm; exit $$lint
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --durations=30

bench: install-dev
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) build dist .pytest_cache
