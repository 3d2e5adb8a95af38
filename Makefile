# vessel_kinematics: the two commands of the README, and the steps behind them.
#   make demo   simulate a voyage, run the navigator over DDS on it, record, plot, score
#   make test   the whole test suite (builds everything it needs first)
SHELL := /bin/bash
.DEFAULT_GOAL := help

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
# The shared directory beside the repository (CI lays it there too): ROS interface sources.
SHARED ?= ../shared
# tf2_msgs, which the PyPI wheels lack, built from source into the same install/ space.
TF2_MSGS := $(SHARED)/ros/tf2_msgs
TF2_STAMP := $(VENV)/.tf2-installed
# The Python and numpy of an apt-installed Jazzy (Ubuntu 24.04): the tests that need no ROS run
# there too, in .venv312, from pyenv's 3.12 (CI has it; its absence is an error, not a skip).
PYTHON312 ?= $(shell pyenv root 2>/dev/null)/versions/3.12.1/bin/python
VENV312 := .venv312
STAMP312 := $(VENV312)/.installed
CORE_TESTS := test/test_rotation.py test/test_quaternion.py test/test_geodesy.py \
	test/test_flow.py test/test_frames.py test/test_estimator.py test/test_static_tf.py

.PHONY: help venv build test test312 lint demo bench clean

help:
	@echo 'make demo   run the navigator on the bundled simulated voyage (sets everything up)'
	@echo 'make test   run the whole test suite (sets everything up)'
	@echo 'make bench  print the benchmarks'

$(STAMP): .ci/requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install --upgrade --quiet pip
	$(VPY) -m pip install --quiet -r .ci/requirements.txt
	touch $(STAMP)

# The CMake and rosidl generator wheels that build tf2_msgs, and the two paths baked into the
# ROS wheels' CMake exports rewritten to this venv's (inside the venv only).
$(TF2_STAMP): $(STAMP) .ci/requirements-tf2.txt .ci/venv_cmake_paths.py
	$(VPY) -m pip install --quiet -r .ci/requirements-tf2.txt
	$(VPY) .ci/venv_cmake_paths.py
	touch $(TF2_STAMP)

venv: $(STAMP)

build: $(TF2_STAMP)
	@test -f $(TF2_MSGS)/package.xml || { echo "no $(TF2_MSGS): set SHARED=" >&2; exit 1; }
	source $(VENV)/bin/activate && CMAKE_PREFIX_PATH=$$VIRTUAL_ENV \
	    AMENT_PREFIX_PATH=$$VIRTUAL_ENV colcon --log-base log build \
	    --base-paths . $(TF2_MSGS) --build-base build --install-base install \
	    --cmake-args -DBUILD_TESTING=OFF
	@test -x install/vessel_kinematics/lib/vessel_kinematics/navigator
	$(ACTIVATE) && python -c 'import tf2_msgs.msg'

$(STAMP312): .ci/requirements-py312.txt
	@test -x "$(PYTHON312)" || { echo "no Python 3.12 at '$(PYTHON312)' (pyenv install 3.12.1, \
	    or make PYTHON312=/path/to/python3.12)" >&2; exit 1; }
	$(PYTHON312) -m venv $(VENV312)
	$(VENV312)/bin/python -m pip install --upgrade --quiet pip
	$(VENV312)/bin/python -m pip install --quiet -r .ci/requirements-py312.txt
	touch $(STAMP312)

test: build test312
	$(ACTIVATE) && VK_INSTALL=$(CURDIR)/install python -m pytest test

# The core and estimator tests under Python 3.12 + numpy 1.26.4 (no ROS, no DDS).
test312: $(STAMP312)
	PYTHONPATH=$(CURDIR):$(CURDIR)/test $(VENV312)/bin/python -m pytest -q -p no:cacheprovider \
	    $(CORE_TESTS)

lint: build
	$(ACTIVATE) && python -m pytest test/test_flake8.py test/test_pep257.py

demo: build
	$(ACTIVATE) && python -m vessel_kinematics.tools.demo --output demo_out

bench: build
	$(ACTIVATE) && for b in bench/bench_*.py; do echo "== $$b"; python $$b || exit 1; done

clean:
	rm -rf build install log demo_out
