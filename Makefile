# Quick start: `make demo` and `make test` each set up a virtual environment first.
# `make demo` installs robocal with the report extra only (numpy, scipy, PyYAML, threadpoolctl,
# matplotlib), without precompiled bytecode (Python compiles what it imports);
# `make test` adds the test extra (pytest, hypothesis, playwright, example-robot-data, rosbags).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO_STAMP := $(VENV)/.installed-demo
TEST_STAMP := $(VENV)/.installed-test

.PHONY: demo test bench clean

$(VENV)/bin/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

$(DEMO_STAMP): pyproject.toml $(VENV)/bin/python
	$(BIN)/python -m pip install --quiet --no-compile -e ".[report]"
	touch $(DEMO_STAMP)

$(TEST_STAMP): pyproject.toml $(VENV)/bin/python
	$(BIN)/python -m pip install --quiet -e ".[test,report]"
	touch $(TEST_STAMP)

demo: $(DEMO_STAMP)
	$(BIN)/python examples/th8/reproduce.py --out runs/th8

test: $(TEST_STAMP)
	$(BIN)/python -m pytest

bench: $(DEMO_STAMP)
	$(BIN)/python benchmarks/bench_identify.py
	$(BIN)/python benchmarks/bench_limit.py
	$(BIN)/python benchmarks/bench_plan.py

clean:
	rm -rf $(VENV) runs test-artifacts
