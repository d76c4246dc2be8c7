# Entry points.  Every target creates the virtual environment it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint typecheck pytest bench bench-solvers bench-tracking clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,bench]'
	touch $(STAMP)

venv: $(STAMP)

## run: the main job (until the service lands: the engine on an example contour)
run: $(STAMP)
	$(BIN)/python -c 'import json, math; n = 8; \
	  nodes = [[100 + 40 * math.cos(2 * math.pi * i / n), 100 + 40 * math.sin(2 * math.pi * i / n)] for i in range(n)]; \
	  forces = [[10.0, 0.0] if i == 0 else [0.0, 0.0] for i in range(n)]; \
	  print(json.dumps({"nodes": nodes, "forces": forces}))' \
	| $(BIN)/efdm deform - --stiffness 2

## test: lint, type-check and the whole test suite
test: lint typecheck pytest

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(STAMP)
	$(BIN)/mypy

pytest: $(STAMP)
	$(BIN)/python -m pytest -q

## bench: every benchmark; results land in bench/results/
bench: bench-solvers bench-tracking

bench-solvers: $(STAMP)
	$(BIN)/python bench/solvers.py

bench-tracking: $(STAMP)
	$(BIN)/python bench/tracking.py

clean:
	rm -rf $(VENV) .mypy_cache .pytest_cache .ruff_cache
