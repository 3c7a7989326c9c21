# `make demo` runs the main job, `make test` the tests, `make docs` builds the site, `make lint` checks style;
# `make fly-demo` flies 5 simulated ArduCopters through `uav-swarm fly` (AUTOPILOT=px4: PX4).
# ARGS adds flags to the demo's command: make demo ARGS="--no-telemetry --duration-s 60"
# Each creates .venv (Python >= 3.11) and installs only what it needs: the demo the package itself, the
# tests and the site the package with TEST_EXTRAS (the extras of pyproject.toml; the README and
# docs/index.md name the same, tests/test_install_lines.py checks it). torch comes from pip's configured
# index (PyPI by default, where the Linux wheel is the CUDA build); for the CPU-only build give its index:
#   make demo TORCH_INDEX=https://download.pytorch.org/whl/cpu
TEST_EXTRAS := test,distributed,marl,docs,ros2
VENV ?= .venv
PYTHON ?= python3
TORCH ?= torch==2.13.0
TORCH_INDEX ?=
AUTOPILOT ?= ardupilot
ARGS ?=
# PYTEST_ARGS adds flags to the tests' command: "-n auto" spreads them over every core (pytest-xdist);
# CI runs the slow tests too and prints the slowest 20: make test PYTEST_ARGS="-m 'not sitl and not ns3' --durations=20"
PYTEST_ARGS ?=
PY := $(VENV)/bin/python
PIP := $(PY) -m pip install --quiet
TORCH_FROM := $(if $(TORCH_INDEX),--index-url $(TORCH_INDEX),)

.PHONY: demo fly-demo test install install-test lint docs

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PIP) --upgrade pip

$(VENV)/.demo-installed: pyproject.toml | $(PY)
	$(PIP) $(TORCH_FROM) "$(TORCH)"
	$(PIP) -e . "$(TORCH)"  # torch pinned: the build installed above stays
	touch $@

$(VENV)/.test-installed: pyproject.toml $(VENV)/.demo-installed
	$(PIP) -e ".[$(TEST_EXTRAS)]" "$(TORCH)"  # torch pinned: no extra may move it
	touch $@

install: $(VENV)/.demo-installed

install-test: $(VENV)/.test-installed

demo: $(VENV)/.demo-installed
	$(VENV)/bin/uav-swarm simulate --out out/simulate $(ARGS)

fly-demo: $(VENV)/.demo-installed
	$(VENV)/bin/uav-swarm fly --simulated $(AUTOPILOT) --duration-s 60 --speedup 2 --out out/fly-$(AUTOPILOT) $(ARGS)

test: $(VENV)/.test-installed
	$(PY) -m pytest -q $(PYTEST_ARGS)

lint: $(VENV)/.test-installed
	$(VENV)/bin/ruff check .
	$(PY) -m mypy

docs: $(VENV)/.test-installed
	NO_MKDOCS_2_WARNING=1 $(VENV)/bin/mkdocs build --strict --site-dir site
