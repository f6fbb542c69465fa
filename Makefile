# autoscoop: `make demo` and `make test` on a fresh machine.
# torch==2.13.0 goes first: on these machines that is a local CPU build (a plain `torch` would pull
# several GB of CUDA packages); then the package with its extras.

VENV    ?= .venv
PYTHON  ?= python3
PIP     := $(VENV)/bin/pip
BIN     := $(VENV)/bin
EXTRAS  := train,deploy,media

.PHONY: demo test install install-test system-deps bench clean

$(VENV)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PIP) install torch==2.13.0
	$(PIP) install -e ".[$(EXTRAS)]"
	touch $@

$(VENV)/.installed-test: $(VENV)/.installed
	$(PIP) install -e ".[$(EXTRAS),sweep,ros2,test]"
	touch $@

install: $(VENV)/.installed

install-test: $(VENV)/.installed-test

demo: install system-deps
	$(BIN)/autoscoop demo

# System packages the tests need, installed when missing and root.
system-deps:
	@bash tools/system_deps.sh

# Three workers, a test file each at a time (--dist loadfile), the longest files first (tests/conftest.py):
# on two cores a third keeps them busy while the others wait on real-time ROS runs and Ray's start.
TEST_WORKERS ?= 3
test: install-test system-deps
	$(BIN)/pytest --numprocesses $(TEST_WORKERS) --dist loadfile --durations=15

bench: install
	$(BIN)/autoscoop bench --json benchmarks/results/speed/bench.json

clean:
	rm -rf $(VENV) *.egg-info out
