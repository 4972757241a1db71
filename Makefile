# Two commands on a fresh machine: `make demo` (the main job) and `make test` (every test).
# Each bootstraps what it needs: a virtual environment with the pinned requirements, then
# `colcon build` of ros2_ws. Both steps are skipped when nothing they depend on changed.

SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
WS := ros2_ws
VENV_STAMP := $(VENV)/.requirements.stamp
BUILD_STAMP := $(WS)/install/.build.stamp
SOURCES := $(shell find $(WS)/src -type f -not -path '*/__pycache__/*' -not -name '*.pyc' \
                   -not -path '*/.pytest_cache/*')
# Every command below runs inside the venv with the workspace overlay sourced, as a user
# would after `source install/setup.bash`.
RUN := source $(VENV)/bin/activate && source $(WS)/install/local_setup.sh &&
PYTEST_ARGS ?=
# The pool of ROS domains of every run, study, report and test (ibvs_bringup.domains): within
# 0-101, the range ROS 2 documents as safe on Linux.
IBVS_ROS_DOMAINS ?= 0-101
export IBVS_ROS_DOMAINS

.PHONY: all check-system venv build test fuzz demo report vsbench bench lint lock clean
all: build

check-system:
	tools/check_system.sh $(PYTHON)

# requirements-test.txt: test-only peer packages, without their declared dependencies
# (they would pull opencv-python over the headless cv2; see the file).
# tools/fix_cmake_exports.py: the message wheels' CMake exports name their build machine's
# Python headers; the interface package ros2_ws/src/tf2_msgs needs this machine's.
# tools/check_system.sh: what the system must have (Python 3.11 with venv and headers, CMake,
# a C and a C++ compiler), checked before anything is made; it names the Debian package of
# each missing piece (README: the one apt-get line).
$(VENV_STAMP): requirements.txt requirements-test.txt
	tools/check_system.sh $(PYTHON)
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/pip install --quiet --disable-pip-version-check -r requirements.txt
	$(VENV)/bin/pip install --quiet --disable-pip-version-check --no-deps \
	  -r requirements-test.txt
	$(VENV)/bin/python tools/fix_cmake_exports.py
	touch $@

venv: $(VENV_STAMP)

# The interface package (tf2_msgs, CMake) finds the ROS packages of the venv through
# AMENT_PREFIX_PATH; its linter tests are not built (they would need ament_cppcheck).
# PYTHONDONTWRITEBYTECODE (set on some machines) makes setuptools warn "byte-compiling is
# disabled" on stderr for every package, which colcon reports as "had stderr output".
$(BUILD_STAMP): $(VENV_STAMP) $(SOURCES)
	tools/check_system.sh $(PYTHON)
	source $(VENV)/bin/activate && cd $(WS) && unset PYTHONDONTWRITEBYTECODE && \
	  AMENT_PREFIX_PATH=$$VIRTUAL_ENV$${AMENT_PREFIX_PATH:+:$$AMENT_PREFIX_PATH} \
	  colcon --log-base log build --merge-install --event-handlers console_direct- summary+ \
	  --cmake-args -DBUILD_TESTING=OFF
	touch $@

build: $(BUILD_STAMP)

# The linters in a pytest process of their own (flake8 forks workers, and a fork of a process
# that holds rclpy objects from earlier node tests can crash in the child), at the same time
# as the rest, their report printed after it: the rest runs in two worker processes
# (pytest-xdist, a file per worker at a time) whose graph tests are latency-bound (about 1.2
# of 2 cores), which leaves room for the linters' 20-odd seconds of CPU. Each worker is its
# own process with its own ROS domain (ibvs_testing.isolation.isolate, called from the root
# conftest.py). make test fails if either fails; PYTEST_ARGS='-k NAME' may select no linter.
test: build
	$(RUN) lint_log=$$(mktemp) && \
	  { python -m pytest -m linter -p no:cacheprovider $(PYTEST_ARGS) > $$lint_log 2>&1 & \
	    lint_pid=$$!; } && \
	  { python -m pytest -m 'not linter' -n 2 --dist loadfile $(PYTEST_ARGS); tests=$$?; } ; \
	  wait $$lint_pid; lint=$$?; [ $$lint -eq 5 ] && lint=0; \
	  echo '--- linters (ran alongside; exit 5: none selected by PYTEST_ARGS) ---'; \
	  cat $$lint_log; \
	  rm -f $$lint_log; echo "linters: exit $$lint; other tests: exit $$tests"; \
	  [ $$tests -eq 0 ] && [ $$lint -eq 0 ]

# Bad input into every subscribed topic of every node (tests/fuzz; make test runs it too).
fuzz: build
	$(RUN) python -m pytest tests/fuzz $(PYTEST_ARGS)

demo: build
	$(RUN) python -m ibvs_experiments.cli demo

report: build
	$(RUN) python -m ibvs_experiments.cli report

# The workspace benchmark (docs/vsbench.md): 500 tasks x 3 laws x 7 latency points through the
# model loop, the first 100 through the graph (its first 10 at every latency);
# VSBENCH_ARGS='--tasks 50 --graph-tasks 10' for a reduced run.
VSBENCH_ARGS ?=
vsbench: build
	$(RUN) python -m ibvs_experiments.vsbench $(VSBENCH_ARGS)

bench: build
	$(RUN) python -m ibvs_experiments.bench

lint: build
	$(RUN) python -m pytest -m linter

# Re-pin requirements.txt from requirements.in: what pip would install into an empty venv.
# (pip freeze would list the message packages that the ROS wheels embed as egg-info,
# which are not installable by name.)
lock:
	$(PYTHON) -m pip install --quiet --dry-run --ignore-installed --report .lock.json \
	  -r requirements.in
	$(PYTHON) -c "import json; r = json.load(open('.lock.json')); \
	  print('# Pinned by make lock from requirements.in (Python 3.11, Linux x86_64).'); \
	  print('\n'.join(sorted(i['metadata']['name'] + '==' + i['metadata']['version'] \
	  for i in r['install'])))" > requirements.txt
	rm -f .lock.json

clean:
	rm -rf $(WS)/build $(WS)/install $(WS)/log
