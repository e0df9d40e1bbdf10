# Set-up is part of every target: a fresh clone needs only Python 3.11+.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo check test bench docs clean install

# uv installs from its cache in parallel and compiles nothing: Python byte-compiles a module
# the first time a process imports it and later processes read the compiled file (the test
# suite imports about 3,700 of the environment's 10,000 modules). Every recipe lets Python
# write that bytecode into the environment and the sources, also where the caller's
# environment forbids it (PYTHONDONTWRITEBYTECODE=1, common in containers and CI), in which
# case every process the tests start would compile numpy, scipy, numba and robofleet again.
unexport PYTHONDONTWRITEBYTECODE

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check uv
	$(BIN)/uv pip install --quiet --python $(BIN)/python -e ".[all]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/robofleet run scenarios/avoidance/circle_swap.yaml --seed 1 --out runs/demo --overwrite --animate

# two workers; each takes the next test (or the next file of tests sharing a fixture) when
# it is free, in the order tests/conftest.py gives: the long tests first
PYTEST := MPLBACKEND=Agg $(BIN)/python -m pytest -n 2 --dist loadgroup --no-loadscope-reorder -q

check: $(STAMP)
	$(PYTEST) -m "not slow and not extended"

test: $(STAMP)
	@command -v chromium >/dev/null || echo "note: no chromium on PATH: the browser tests of the replay pages (tests/viz) are skipped (apt-get install chromium)"
	$(PYTEST)

docs: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m sphinx -W --keep-going -q -b html docs docs/_build/html

bench: $(STAMP)
	$(BIN)/uv pip install --quiet --python $(BIN)/python -e ".[bench]"
	$(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) runs .pytest_cache docs/_build docs/api/generated dist
