# driftmap: `make demo` sets everything up and runs the main job; `make test` sets up and runs every check.
SHELL := /bin/bash
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO_DIR ?= data/demo
DEMO_SEED ?= 7
DEMO_PORT ?= 8000

.PHONY: lock demo test lint typecheck imports pytest bench clean frontend frontend-test frontend-lint frontend-api system-packages

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# Runtime install at the versions of requirements.lock: re-run whenever pyproject.toml or the lock changes.
$(VENV)/.installed-run: pyproject.toml requirements.lock | $(BIN)/python
	$(BIN)/pip install --quiet -c requirements.lock -e .
	touch $@

# Development install (tests, linters, type checker).
$(VENV)/.installed-dev: pyproject.toml requirements.lock | $(BIN)/python
	$(BIN)/pip install --quiet -c requirements.lock -e '.[dev]'
	touch $@ $(VENV)/.installed-run

# The lock: the newest versions pyproject.toml allows, installed into a scratch venv and frozen.
lock:
	rm -rf build/lock-venv && $(PYTHON) -m venv build/lock-venv
	build/lock-venv/bin/pip install --quiet --upgrade pip && build/lock-venv/bin/pip install --quiet '.[dev]'
	{ sed -n '1,2p' requirements.lock; build/lock-venv/bin/pip freeze --exclude-editable | grep -v '^driftmap @'; } > requirements.lock.new
	mv requirements.lock.new requirements.lock && rm -rf build/lock-venv

# Browser UI (frontend/): npm ci when the lock file changes, then a vite build into frontend/dist.
frontend/node_modules/.installed: frontend/package-lock.json
	cd frontend && npm ci --no-audit --no-fund
	touch $@

frontend: frontend/node_modules/.installed
	cd frontend && npm run build

frontend-test: frontend
	cd frontend && npm test -- --run

# ESLint and Prettier over frontend/, then src/api/schema.d.ts against the app's OpenAPI (the app's own schema,
# dumped with the venv's Python; `make frontend-api` regenerates the file).
frontend-lint: frontend/node_modules/.installed $(VENV)/.installed-dev
	cd frontend && npm run lint
	cd frontend && PYTHON=$(abspath $(BIN)/python) npm run check:api

frontend-api: frontend/node_modules/.installed $(VENV)/.installed-run
	cd frontend && PYTHON=$(abspath $(BIN)/python) npm run gen:api

# Debian packages the tests run against: chromium for the browser end-to-end tests (tests/e2e),
# redis-server for the job queue and live hub on Redis, postgresql for the PostgreSQL run of the suite and the
# scale-out topology test (tests/topology). The tests start private servers of their own; nothing system-wide.
SYSTEM_PACKAGES := chromium redis-server postgresql
system-packages:
	@missing=""; for p in $(SYSTEM_PACKAGES); do dpkg -s $$p >/dev/null 2>&1 || missing="$$missing $$p"; done; \
	if [ -n "$$missing" ]; then apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y $$missing; fi

demo: $(VENV)/.installed-run frontend
	rm -rf $(DEMO_DIR)
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap simulate --seed $(DEMO_SEED) --size small --out $(DEMO_DIR)/site
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap site create demo --survey $(DEMO_DIR)/site/survey.dxf --drives $(DEMO_DIR)/site/drives
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap drive list demo
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap map build demo
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap map show demo
	DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap localise demo $(DEMO_DIR)/site/drives/loc-01 --out $(DEMO_DIR)/loc-01.csv
	@# an admin with a generated password, then the server with the UI and the localisation drives (clean
	@# copies: loc-NN) replayed as live vehicles through the frame endpoint, looping, until Ctrl-C
	@password=$$($(BIN)/python -c 'import secrets; print(secrets.token_urlsafe(12))') && \
	echo "$$password" | DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap user add admin --role admin --password-stdin && \
	echo "demo: starting the server on http://127.0.0.1:$(DEMO_PORT) (log: $(DEMO_DIR)/serve.log) and replaying $$(cd $(DEMO_DIR)/site/drives && echo loc-??) as live vehicles; Ctrl-C stops everything" && \
	echo "$$password" | DRIFTMAP_DATA_DIR=$(DEMO_DIR) $(BIN)/driftmap replay demo $(DEMO_DIR)/site/drives/loc-?? \
		--serve --url http://127.0.0.1:$(DEMO_PORT) --user admin --password-stdin --show-login

lint: $(VENV)/.installed-dev
	$(BIN)/ruff check backend tests bench
	$(BIN)/ruff format --check backend tests bench

typecheck: $(VENV)/.installed-dev
	$(BIN)/mypy

imports: $(VENV)/.installed-dev
	$(BIN)/lint-imports

# Every test on the embedded SQLite default, then again on PostgreSQL (a private server) the tests of the server
# side that touch the database (marked `db` by tests/conftest.py): store, services, API, jobs and live. The CLI,
# the reports and the browser tests call those same services, so one database is enough for them; the topology
# test (tests/topology) always runs on PostgreSQL + Redis. Each run spreads its test files over TEST_PROCESSES
# processes (pytest-xdist; most of a test's time is spent waiting on servers, browsers and workers, so more
# processes than cores pay) and prints its 15 slowest steps.
PG_TESTS := tests/store tests/services tests/api tests/jobs tests/live
TEST_PROCESSES ?= 3
pytest: $(VENV)/.installed-dev frontend system-packages
	$(BIN)/pytest -q -n $(TEST_PROCESSES) --dist loadfile --durations=15 --database sqlite
	$(BIN)/pytest -q -n $(TEST_PROCESSES) --dist loadfile --durations=15 --database postgresql -m db $(PG_TESTS)

test: lint typecheck imports frontend-lint frontend-test pytest

BENCHES := bench_import bench_simulate bench_sad kitti_odometry bench_loops bench_posegraph bench_topomap bench_mapping \
	bench_localise bench_thumbnails vpr_outside bench_survey_layers bench_live bench_fleet soak_live bench_refusals bench_history bench_incremental bench_scaling bench_ui fuzz_api

bench: $(VENV)/.installed-dev frontend system-packages
	@for b in $(BENCHES); do echo "== bench/$$b.py"; $(BIN)/python bench/$$b.py || exit 1; done

clean:
	rm -rf $(VENV) data .mypy_cache .ruff_cache .pytest_cache
