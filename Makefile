# Two entry points for a new user: `make demo` (the sensor end to end on simulated grasps) and
# `make test` (the whole suite). Both create .venv and install everything they need.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench docs reproduce reproduce-full reproduce-quick clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	# A pinned torch takes the local CPU build; a range would pull CUDA packages.
	$(BIN)/pip install -q torch==2.13.0
	$(BIN)/pip install -q -e ".[test,dask,peers]"
	touch $(STAMP)

demo: $(STAMP)
	PATH="$(abspath $(BIN)):$$PATH" bash examples/demo.sh

test: $(STAMP)
	# one worker per core, at most four: most tests wait on subprocesses or run one thread
	PATH="$(abspath $(BIN)):$$PATH" $(BIN)/python -m pytest -q -p no:cacheprovider -n auto --maxprocesses 4

bench: $(STAMP)
	$(BIN)/python -m pytest -q -s tests/bench -o addopts=""

docs: $(STAMP)
	$(BIN)/python -m neurotac_cli.docgen docs/commands

reproduce: $(STAMP)
	PATH="$(abspath $(BIN)):$$PATH" $(MAKE) -C examples reproduce

reproduce-full: $(STAMP)
	PATH="$(abspath $(BIN)):$$PATH" $(MAKE) -C examples reproduce-full

reproduce-quick: $(STAMP)
	PATH="$(abspath $(BIN)):$$PATH" $(MAKE) -C examples reproduce-quick

clean:
	rm -rf $(VENV) demo-out .pytest_cache
