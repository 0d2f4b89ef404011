# gnss_ins: one-command set-up, demo and tests.
# Creates .venv; installs rclpy and the ROS message packages from PyPI unless a ROS 2 Jazzy
# install is sourced (then the venv sees the system packages instead).

PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
ROS_SYSTEM := $(shell [ "$$ROS_DISTRO" = "jazzy" ] && $(PYTHON) -c 'import rclpy' 2>/dev/null && echo yes)
# Pure cores (no rclpy import) checked by mypy --strict; ROS modules are node.py / ros_*.py.
MYPY_TARGETS := gnss_ins_common imu400cc_driver gnss_driver ins_fusion/core ins_fusion/sim \
	ins_fusion/qfree.py ins_fusion/qfree_checks.py ins_fusion/tools/bag_io.py ins_fusion/tools/bag_recover.py \
	ins_fusion/tools/recover.py ins_fusion/tools/progress.py \
	ins_fusion/fusion_params.py ins_fusion/messages_in.py ins_fusion/solution_out.py ins_fusion/replay \
	ins_fusion/noise_id ins_fusion/calibration_id ins_fusion/tools/calibrate.py ins_fusion/tools/allan.py

.PHONY: all venv demo test lint typecheck pytest bench colcon clean

all: test

$(BIN)/.installed: setup.py Makefile
	$(PYTHON) -m venv $(if $(ROS_SYSTEM),--system-site-packages) $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
ifeq ($(ROS_SYSTEM),yes)
	@echo "Using the sourced ROS 2 $$ROS_DISTRO installation for rclpy and messages."
else
	$(BIN)/pip install --quiet 'ros-jazzy-rclpy[fastrtps]' ros-jazzy-common-interfaces
endif
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

venv: $(BIN)/.installed

demo: venv
	$(BIN)/gnss_ins demo

lint: venv
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: venv
	$(BIN)/mypy $(MYPY_TARGETS)

pytest: venv
	$(BIN)/python -m pytest -q

test: lint typecheck pytest

bench: venv
	@for b in bench/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache .hypothesis
