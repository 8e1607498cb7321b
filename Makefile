# dualpilot: `make run` flies a mission, `make test` runs every test.
# Both create .venv and install the pinned dependencies on first use.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= runs/latest
SPEED ?= 20
# The mission: empty flies the default mission, the one `docker compose up` and `dualpilot
# mission` fly too (DEFAULT_MISSION in dualpilot/mission/config.py: lookahead+risk, seed 7,
# paper timing, today's reading; tests/integration/test_compose.py checks they agree).
# CONTROLLER: cc, s1, s2, concurrent, lookahead or an installed supervisor (docs/extending.md),
# each also with +risk (dualpilot evaluate's names)
CONTROLLER ?=
SEED ?=
TIMING ?=
PROFILE ?=
SUPERVISOR ?=
MISSION_FLAGS = $(strip $(if $(CONTROLLER),--controller $(CONTROLLER)) $(if $(SEED),--seed $(SEED)) \
	$(if $(TIMING),--timing $(TIMING)) $(if $(PROFILE),--profile $(PROFILE)) \
	$(if $(SUPERVISOR),--supervisor $(SUPERVISOR)))
# VIEWER=1: also the live view (services/viewer): the web page on http://127.0.0.1:8766/ and
# Foxglove WebSocket on ws://127.0.0.1:8765 (free ports when taken; the launcher prints them)
VIEWER ?=
# TLS=1: mutual TLS and the router's access control (services/common/acl.py), off by default
# (every service then a Zenoh client, one hop more per query than the default peers);
# certificates from CERTS (made there if missing), else made in $(OUT)/tls
TLS ?=
CERTS ?=
TLS_FLAGS := $(if $(TLS),$(if $(CERTS),--tls-dir $(CERTS),--tls))

.PHONY: setup browser run certs mission proto test test-fast flake-hunt lint bench docs figures clean compose-check

setup: $(STAMP)

# Debian's chromium, the headless browser of the web page's test (apt, as root; a no-op when
# /usr/bin/chromium is there): scripts/install_browser.sh. `make test` runs it first.
browser:
	sh scripts/install_browser.sh

$(STAMP): pyproject.toml scripts/pyretechnics-requirements.txt examples/dualpilot-example/pyproject.toml
	test -x $(BIN)/python || $(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	# the example plug-in (a System 1 method and a supervisor found through entry points:
	# docs/extending.md), tested in-process and through the stack
	$(BIN)/python -m pip install --quiet --no-deps -e examples/dualpilot-example
	# MAVSDK's native 4.x binding in a directory of its own: it is the module mavsdk too, as
	# mavsdk<4 in dev (pyproject.toml, extra mavsdk4; tests/e2e/test_mavsdk_examples.py)
	$(BIN)/python -m pip install --quiet --no-deps --upgrade --target $(VENV)/mavsdk4 \
		"$$($(BIN)/python -c 'import tomllib; print(*tomllib.load(open("pyproject.toml", "rb"))["project"]["optional-dependencies"]["mavsdk4"])')"
	# the physics fire process's library, built against our numpy/scipy pins (~4 min once)
	sh scripts/install_pyretechnics.sh $(BIN)/python
	$(BIN)/python -m dualpilot.warmup  # compiles the Numba kernels into their disk cache
	# and the default mission's own (forecast, risk zones, lattice), from its first 12 steps
	$(BIN)/python -m dualpilot.cli mission --max-steps 12 --no-figures --quiet --out $(VENV)/warm-mission
	touch $(STAMP)

# the distributed stack: a Zenoh router and the five services as processes on loopback
# (services/launch/ reads docker-compose.yml, the one description of the services)
run: setup
	$(BIN)/python -m services.launch $(MISSION_FLAGS) --speed-factor $(SPEED) --out $(OUT) \
		$(TLS_FLAGS) $(if $(VIEWER),--viewer)

# a local CA and a key and certificate per service (ZENOH_TLS_DIR; docker-compose.yml)
certs: setup
	$(BIN)/python -m services.certs --out $(or $(CERTS),runs/certs)

# the same mission in one process (no Zenoh, no MAVLink)
mission: setup
	$(BIN)/dualpilot mission $(MISSION_FLAGS) --out $(OUT)

# regenerate services/msgs from proto/ (a test fails when they differ)
proto: setup
	$(BIN)/python -m services.protogen --clean

# every tier (unit, integration, e2e; tests/conftest.py): the integration and e2e tests on two
# pytest-xdist workers (a test file whole on one), their 25 slowest listed at the end, and the
# unit tests beside them on two more at the lowest CPU priority (nice 19): scripts/test_lanes.sh
# (STACK_WORKERS, UNIT_WORKERS), docs/testing.md.
# TEST_WORKERS=N runs every tier on N pytest-xdist workers instead (tests/support/parallel.py).
E2E_LANES ?= 1
export E2E_LANES
TEST_WORKERS ?= 0
PARALLEL = $(if $(filter-out 0,$(TEST_WORKERS)),-n $(TEST_WORKERS) --dist loadgroup --no-loadscope-reorder,)
test: setup browser
	$(if $(PARALLEL),$(BIN)/python -m pytest -q --durations=25 $(PARALLEL),scripts/test_lanes.sh)

# the inner loop: the unit tier without its slow tests (under 2 min)
test-fast: setup
	$(BIN)/python -m pytest -q -m "unit and not slow"

# N runs of a tier beside CPU load, every test that ever failed (scripts/flake_hunt.sh)
RUNS ?= 10
LOAD ?= 0
TIER ?= fast
flake-hunt: setup
	scripts/flake_hunt.sh -n $(RUNS) -l $(LOAD) -t $(TIER)

lint: setup
	$(BIN)/ruff check .
	$(BIN)/mypy dualpilot services tests benchmarks examples/dualpilot-example/src

bench: setup
	$(BIN)/dualpilot bench system1 --out runs/bench
	$(BIN)/dualpilot bench system2 --instances 20 --reference-timeout 30 --out runs/bench
	$(BIN)/dualpilot bench certify --out runs/bench --figure runs/bench/certify_gap_vs_time.png

# the documentation site (mkdocs.yml, docs/) into site/; --strict: a broken link fails it
docs: setup
	$(BIN)/mkdocs build --strict --site-dir site

# the deployment test bed (root): the air, ground and gcs hosts as network namespaces, the
# radio link shaped by LINK_ARGS (e.g. "--delay-ms 150 --jitter-ms 20 --loss 0.05 --rate-mbit 1");
# prints the hosts and waits, Ctrl-C takes it all down (docs/testbed.md)
.PHONY: testbed testbed-down
LINK_ARGS ?=
testbed: setup
	$(BIN)/python -m services.testbed up $(LINK_ARGS)

# remove what test beds whose owner process died left behind
testbed-down: setup
	$(BIN)/python -m services.testbed down

# one whole mission across the test bed's hosts with a 10 s outage of the air–ground link
# mid-mission (tests/e2e/test_testbed.py, the first test), its run directory under runs/
.PHONY: testbed-check
ifeq ($(origin TESTBED_RUN_DIR), undefined)
TESTBED_RUN_DIR := runs/$(shell date +%Y%m%d-%H%M%S)-testbed-check
endif
testbed-check: setup
	TESTBED_RUN_DIR=$(TESTBED_RUN_DIR) $(BIN)/python -m pytest -q -p no:cacheprovider \
		tests/e2e/test_testbed.py -k outage -rs; rc=$$?; \
		echo "run directory: $(TESTBED_RUN_DIR)"; exit $$rc

# `docker compose up` for real (root; installs docker.io/docker-compose/debootstrap, starts and
# stops its own dockerd, builds a debootstrap base, flies one mission): scripts/compose_check.sh
compose-check:
	scripts/compose_check.sh

clean:
	rm -rf $(VENV) runs site .pytest_cache .mypy_cache .ruff_cache *.egg-info
