# sela_ros: `make demo` runs the mission, `make test` runs the tests. Both create .venv first.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PKG_SOURCES := $(shell find sela_ros sim_bridge -name '*.py' -o -name '*.urdf' -o -name '*.npz' 2>/dev/null) \
	setup.py setup.cfg package.xml resource/sela_ros $(wildcard config/*.yaml config/*.xml config/maps/* launch/*.py rviz/*.rviz)

# DDS stays on loopback: Fast DDS with config/fastdds_loopback.xml (UDP on 127.0.0.1 and
# shared memory only; SYSTEM_DEFAULT is the discovery range in which the rmw applies the
# profile as it is: LOCALHOST would add send sockets on every interface). The programs set
# the same themselves (sela_ros/tools/ros_env.py). The venv is the ament prefix that
# `ros2 run`-style lookups use.
export FASTDDS_DEFAULT_PROFILES_FILE := $(abspath config/fastdds_loopback.xml)
export FASTRTPS_DEFAULT_PROFILES_FILE := $(FASTDDS_DEFAULT_PROFILES_FILE)
export ROS_AUTOMATIC_DISCOVERY_RANGE := SYSTEM_DEFAULT
export RMW_IMPLEMENTATION := rmw_fastrtps_cpp
export AMENT_PREFIX_PATH := $(abspath $(VENV))
export PYTHONDONTWRITEBYTECODE := 1

DEMO_ARGS ?=
TEST_ARGS ?=

.PHONY: venv demo test bench lint clean map8d priors library

venv: $(VENV)/.installed

# Third-party dependencies: only when a requirements file changes. requirements-qd.txt
# (pyribs, Dask) is for the offline map builder; the tests cover it, the nodes never import it.
$(VENV)/.deps: requirements.txt requirements-qd.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip setuptools wheel
	$(PY) -m pip install --quiet -r requirements.txt -r requirements-qd.txt
	@touch $@

# The package itself: a real (non-editable) install, so that setup.py's data_files land in
# $(VENV)/share exactly as colcon puts them in install/, then the executables are mirrored
# into $(VENV)/lib/sela_ros where `ros2 run` looks.
# tf2_msgs (for /tf) and nav2_msgs (the adapter's actions) are not among the PyPI wheels:
# generated from ROS Jazzy's definitions (scripts/interfaces/) with the ROS interface
# generators that are (requirements.txt); rebuilt only when the script or a definition changes.
INTERFACE_SOURCES := $(shell find scripts/interfaces -type f 2>/dev/null)
$(VENV)/.interfaces: $(VENV)/.deps scripts/build_interfaces.py $(INTERFACE_SOURCES)
	$(PY) scripts/build_interfaces.py --prefix $(VENV)
	@touch $@

$(VENV)/.installed: $(VENV)/.deps $(VENV)/.interfaces $(PKG_SOURCES)
	$(PY) -m pip install --quiet --no-deps --no-build-isolation --force-reinstall .
	$(PY) scripts/link_executables.py --prefix $(VENV)
	@rm -rf build *.egg-info
	@touch $@

demo: venv
	$(VENV)/bin/sela-demo $(DEMO_ARGS)

# TEST_ARGS naming test files or folders runs those only; else the whole suite.
TEST_PATHS = $(if $(filter test/% ./test/%,$(TEST_ARGS)),,test)

test: venv
	$(PY) -m pytest $(TEST_PATHS) $(TEST_ARGS)

bench: venv
	$(PY) benchmarks/run_all.py

# The paper's 8-D map in the background; the same target resumes it after any interruption
# (MAPBUILD_DIR, WORKERS, DASK, EVALUATIONS: see scripts/build_map8d.sh).
map8d: venv
	setsid nohup nice -n 10 scripts/build_map8d.sh >/dev/null 2>&1 < /dev/null &
	@echo "building in the background; progress: $${MAPBUILD_DIR:-$${XDG_CACHE_HOME:-$$HOME/.cache}/sela_ros/mapbuild}/build.log"

# SELA's damage priors for the shipped 8-D map: every gait run on each foreseen damage
# (14-21 minutes of one core per damage), then the fast gaits the fall model fears run after
# others (5-7 minutes per front or rear leg); what is in ~/.cache/sela_ros/oracle is free.
# Then the damage library's other conditions are added as the second tier.
PRIORS_DAMAGES ?= single-legs
WORKERS ?= 2
priors: venv
	$(PY) scripts/build_priors.py 8d --damages '$(PRIORS_DAMAGES)' --workers $(WORKERS)
	$(PY) scripts/build_library.py --second-tier library

# The damage library (docs/priors_combination.md): 84 conditions x 4,000 gaits, about 4.7
# core-hours; resumes from the checkpoints in mapbuild/library.
library: venv
	nice -n 15 $(PY) scripts/build_library.py --workers $(WORKERS)
	nice -n 15 $(PY) scripts/build_library.py --assemble

lint: venv
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(VENV) build *.egg-info .pytest_cache
