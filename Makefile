# Entry points.  Every target creates the virtual environment it needs.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: run test lint typecheck pytest bench bench-solvers bench-tracking bench-seeds bench-service bench-load bench-studies clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[service,dev,bench]'
	touch $(STAMP)

venv: $(STAMP)

## run: the main job, the service on its embedded in-memory defaults (127.0.0.1:8000)
run: $(STAMP)
	$(BIN)/efdm serve

## test: lint, type-check and the whole test suite
test: lint typecheck pytest

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

typecheck: $(STAMP)
	$(BIN)/mypy

pytest: $(STAMP)
	$(BIN)/python -m pytest -q

## lint-deploy: hadolint on docker/Dockerfile and the deployment files' checks (tests/deploy,
## also part of `make pytest`)
.PHONY: lint-deploy test-container
lint-deploy: $(STAMP)
	$(BIN)/hadolint docker/Dockerfile
	$(BIN)/python -m pytest -q tests/deploy

## test-container: build the image with podman and run it for real (not part of `make test`;
## needs root, podman, runc and debootstrap: see docker/test-container.sh)
test-container: $(STAMP)
	PYTHON=$(BIN)/python bash docker/test-container.sh

## bench: every benchmark (python -m bench.<family>); results land in bench/results/
bench: bench-solvers bench-tracking bench-seeds bench-service bench-load bench-studies

bench-solvers: $(STAMP)
	$(BIN)/python -m bench.solvers

bench-tracking: $(STAMP)
	$(BIN)/python -m bench.tracking

## bench-seeds: every synthetic condition with seeds 0-23 (8-23: draws nothing was chosen on), efdm only
bench-seeds: $(STAMP)
	$(BIN)/python -m bench.tracking --sets synthetic --trackers efdm --seeds 24 --out bench/results/seeds

## bench-service: a real `efdm serve` on loopback against engine.Tracker in-process (bench/serving)
bench-service: $(STAMP)
	$(BIN)/python -m bench.serving

## bench-studies: the confidence models held out (colour and grey frames), Redis state size
## and resume quality, snapping boxes, several objects (DAVIS, crowd)
bench-studies: $(STAMP)
	$(BIN)/python -m bench.tracking.confidence
	$(BIN)/python -m bench.tracking.confidence --grey
	$(BIN)/python -m bench.serving.state
	$(BIN)/python -m bench.tracking.snap
	$(BIN)/python -m bench.tracking.objects

## bench-load: concurrent WebSocket sessions on 1 and 2 replicas sharing a Redis (redis-server)
bench-load: $(STAMP)
	$(BIN)/python -m bench.load

## clean: the virtual environment, tool caches and __pycache__ (numba's compiled kernels live
## there, and a kernel compiled into a caller is not recompiled when only its callee's file
## changes)
clean:
	rm -rf $(VENV) .mypy_cache .pytest_cache .ruff_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +
