# Quick start: `make demo` and `make test` each set up a virtual environment first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test,report]"
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python examples/th8/reproduce.py --out runs/th8

test: $(STAMP)
	$(BIN)/python -m pytest

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_identify.py
	$(BIN)/python benchmarks/bench_limit.py
	$(BIN)/python benchmarks/bench_plan.py

clean:
	rm -rf $(VENV) runs test-artifacts
