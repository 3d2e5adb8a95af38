# vessel_kinematics: the two commands of the README, and the steps behind them.
#   make demo   simulate a voyage, run the navigator over DDS on it, record, plot, score
#   make test   the whole test suite (builds everything it needs first)
# Everything comes from a clone of this repository and PyPI: the pins are in .ci/.
SHELL := /bin/bash
.DEFAULT_GOAL := help

# The ROS 2 Jazzy wheels on PyPI are built for CPython 3.11.
PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
# Each run gets its own DDS domain unless the caller chose one.
ROS_DOMAIN_ID ?= $(shell echo $$(( ($$$$ % 90) + 10 )))
export ROS_DOMAIN_ID
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST
export RMW_IMPLEMENTATION ?= rmw_fastrtps_cpp
ACTIVATE := source $(VENV)/bin/activate && source install/setup.bash
# The interface packages the PyPI wheels lack (tf2_msgs, geographic_msgs, robot_localization's
# services), kept in the repository and generated into the same install/ space with the rosidl
# wheels (.ci/interfaces/README.md). A hidden folder: a ROS workspace's colcon and rosdep never
# see them, so a real ROS install uses its own.
INTERFACES := .ci/interfaces
ROSIDL_STAMP := $(VENV)/.rosidl-installed
# The Python and numpy of an apt-installed Jazzy (Ubuntu 24.04: Python 3.12, numpy 1.26.4): the
# tests that need no ROS run there too, in .venv312, from the first Python 3.12 found
# (.ci/find_python312) or PYTHON312=/path/to/python3.12. Without one, test312 says so in one
# line and is skipped; with REQUIRE_PY312=1 (.ci/run sets it: CI requires it) that is an error.
PYTHON312 ?=
REQUIRE_PY312 ?=
VENV312 := .venv312
STAMP312 := $(VENV312)/.installed
CORE_TESTS := test/test_rotation.py test/test_quaternion.py test/test_geodesy.py \
	test/test_flow.py test/test_frames.py test/test_estimator.py test/test_static_tf.py

.PHONY: help venv build test test312 test312-run lint demo bench clean

help:
	@echo 'make demo   run the navigator on the bundled simulated voyage (sets everything up)'
	@echo 'make test   run the whole test suite (sets everything up)'
	@echo 'make bench  print the benchmarks'

$(STAMP): .ci/requirements.txt
	@$(PYTHON) -c 'import sys; sys.exit(sys.version_info[:2] != (3, 11))' || { echo "'$(PYTHON)' \
	    is not Python 3.11, which the ROS 2 Jazzy wheels need: make PYTHON=python3.11 ..." >&2; exit 1; }
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --upgrade --quiet pip
	$(VPY) -m pip install --quiet -r .ci/requirements.txt
	touch $(STAMP)

# The CMake and rosidl generator wheels that build the interface packages, and the two paths
# baked into the ROS wheels' CMake exports rewritten to this venv's (inside the venv only).
$(ROSIDL_STAMP): $(STAMP) .ci/requirements-interfaces.txt .ci/venv_cmake_paths.py
	$(VPY) -m pip install --quiet -r .ci/requirements-interfaces.txt
	$(VPY) .ci/venv_cmake_paths.py
	touch $(ROSIDL_STAMP)

venv: $(STAMP)

# The package and the interface packages into install/. An interface package the venv already
# has (a later wheel release) is skipped, never shadowed.
build: $(ROSIDL_STAMP)
	source $(VENV)/bin/activate && \
	    skip=$$(for p in $(INTERFACES)/*/package.xml; do p=$$(basename $$(dirname $$p)); \
	        test -e $$VIRTUAL_ENV/share/ament_index/resource_index/packages/$$p && echo $$p; done); \
	    CMAKE_PREFIX_PATH=$$VIRTUAL_ENV AMENT_PREFIX_PATH=$$VIRTUAL_ENV colcon --log-base log build \
	    --base-paths . $(INTERFACES) --build-base build --install-base install \
	    $${skip:+--packages-skip $$skip} --cmake-args -DBUILD_TESTING=OFF
	@test -x install/vessel_kinematics/lib/vessel_kinematics/navigator
	$(ACTIVATE) && python -c 'import tf2_msgs.msg, geographic_msgs.msg, robot_localization.srv'

test: build test312
	$(ACTIVATE) && VK_INSTALL=$(CURDIR)/install python -m pytest test

# The core and estimator tests under Python 3.12 + numpy 1.26.4 (no ROS, no DDS).
NO312 := no Python 3.12 found (pyenv install 3.12, or make PYTHON312=/path/to/python3.12)
test312:
	@if [ -n '$(PYTHON312)' ]; then py=$$(.ci/find_python312 '$(PYTHON312)') || \
	    { echo 'test312: PYTHON312=$(PYTHON312) is not a Python 3.12' >&2; exit 1; }; \
	else py=$$(.ci/find_python312); fi; \
	if [ -z "$$py" ] && [ -n '$(REQUIRE_PY312)' ]; then \
	    echo 'test312: $(NO312), and REQUIRE_PY312 is set' >&2; exit 1; fi; \
	if [ -z "$$py" ]; then \
	    echo 'test312 skipped: the core and estimator tests under Python 3.12: $(NO312)'; \
	    exit 0; fi; \
	$(MAKE) --no-print-directory test312-run PYTHON312="$$py"

test312-run: $(STAMP312)
	PYTHONPATH=$(CURDIR):$(CURDIR)/test $(VENV312)/bin/python -m pytest -q -p no:cacheprovider \
	    $(CORE_TESTS)

$(STAMP312): .ci/requirements-py312.txt
	$(PYTHON312) -m venv --clear $(VENV312)
	$(VENV312)/bin/python -m pip install --upgrade --quiet pip
	$(VENV312)/bin/python -m pip install --quiet -r .ci/requirements-py312.txt
	touch $(STAMP312)

lint: build
	$(ACTIVATE) && python -m pytest test/test_flake8.py test/test_pep257.py

demo: build
	$(ACTIVATE) && python -m vessel_kinematics.tools.demo --output demo_out

bench: build
	$(ACTIVATE) && for b in bench/bench_*.py; do echo "== $$b"; python $$b || exit 1; done

clean:
	rm -rf build install log demo_out
