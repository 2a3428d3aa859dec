# The README's two commands are `make demo` and `make test`; both set up .venv first.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# One pytest-xdist worker per CPU, at least 2 and at most 4: most ROS tests wait on node processes and discovery, but
# the real-stack tests run controller managers updating at 100 Hz, and four workers on two CPUs stalled them and the
# simulated actuator (timeouts and tolerance holds that pass alone). Each test file runs whole on one worker.
WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); [ $$n -gt 4 ] && n=4; [ $$n -lt 2 ] && n=2; echo $$n)
PARALLEL ?= -n $(WORKERS) --dist loadfile
# The real ros2_control stack for the tests that start it, where no ROS 2 install with it is sourced: an install space
# built for this venv's ROS wheels, taken from beside the checkout when one lies there (the tests skip without it).
FOURBAR_ROS2_CONTROL ?= $(firstword $(wildcard $(abspath $(CURDIR)/..)/shared/ros2-control/install))
export FOURBAR_ROS2_CONTROL

.PHONY: setup demo test test-jitter test-stress test-repeat lint bench-deps bench bench-quick clean

setup:
	@PYTHON=$(PYTHON) VENV=$(VENV) ./scripts/bootstrap.sh
	@if [ -n "$(FOURBAR_ROS2_CONTROL)" ]; then \
	  $(BIN)/python -m pip install --quiet -c requirements/constraints.txt -r requirements/ros2-control.txt; fi

demo: setup
	$(BIN)/fourbar demo --params config/antenna.yaml

lint: setup
	$(BIN)/ruff check fourbar_ros test benchmarks scripts
	$(BIN)/mypy

# Every test once; the statistical repeats (marker `stress`) are left out here and run by test-stress.
test: lint
	$(BIN)/python -m pytest $(PARALLEL)

# The statistical repeats: each stop case STOP_REPEATS times (8 cases: 160 stops), the soaks and long bursts, the
# dense grids and many examples.
STOP_REPEATS ?= 20
test-stress: setup
	FOURBAR_STOP_REPEATS=$(STOP_REPEATS) $(BIN)/python -m pytest -m stress

# The ROS layers N times in a row (default 5), then every failure of every run (test id, first message line);
# nonzero if any run failed. REPEAT_PATHS chooses other tests; the reports stay in REPEAT_KEEP if set.
N ?= 5
REPEAT_PATHS ?= test/node test/live test/package test/commands
test-repeat: setup
	$(BIN)/python scripts/test_repeat.py $(N) $(if $(REPEAT_KEEP),--keep $(REPEAT_KEEP)) -- $(PARALLEL) $(REPEAT_PATHS)

# The pure (non-ROS) tests as if on another CPU (test/support/ulp_jitter.py): every transcendental result of numpy
# moved by one ulp, up or down by a hash (two seeds), then all up, then all down.
JITTER_RUNS ?= --ulp-jitter-seed=0 --ulp-jitter-seed=1 --ulp-jitter-direction=up --ulp-jitter-direction=down
test-jitter: setup
	@set -e; for run in $(JITTER_RUNS); do \
	  echo "test-jitter: $$run"; \
	  $(BIN)/python -m pytest $(PARALLEL) -m 'not ros' --ulp-jitter $$run; \
	done

bench-deps: setup
	$(BIN)/python -m pip install --quiet -c requirements/constraints.txt -r requirements/bench.txt

bench: bench-deps
	$(BIN)/python -m benchmarks.run

bench-quick: bench-deps
	$(BIN)/python -m benchmarks.run --quick

clean:
	rm -rf $(VENV) build install log .pytest_cache .mypy_cache .ruff_cache
