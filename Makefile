# mfc-shm — every target sets itself up on a fresh machine.
SHELL := /bin/bash
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
OUT ?= out
# Compiled plant kernels are cached per machine (content-addressed; a cold cache only costs compile time).
export NUMBA_CACHE_DIR ?= $(HOME)/.cache/mfc-shm/numba
export MPLBACKEND := Agg
export PYTHONHASHSEED := 0

.PHONY: setup system-packages run test test-fast test-slow test-realtime lint typecheck bench bench-extra mutate clean fuzz

KERNELS := $(NUMBA_CACHE_DIR)/.shipped-kernels
setup: $(STAMP) system-packages $(KERNELS)

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

# The shipped compositions' compiled kernels, built once per machine into NUMBA_CACHE_DIR (workbench/warm.py over
# plant/warm.py: tens of seconds each, shm discover's dictionary minutes, printed as they go), so that a fresh clone's
# first command loads machine code instead of compiling. Again when the plant, the discover dictionary, a shipped
# parameter set or scenario changes (it skips what is cached).
$(KERNELS): $(STAMP) $(wildcard plant/*.py plant/effects/*.py workbench/discover/*.py board_config/params/*.toml \
                                board_config/scenarios/*.toml)
	$(BIN)/python -m workbench.warm
	@mkdir -p "$(@D)" && touch "$@"

# Debian packages used by the integration tests (a real Modbus master, pty pairs) and headless Chromium (the HTML
# reports are screenshot in tests/reporting/test_figures_legible.py).
# Never fatal: the tests that need them skip with the reason printed.
system-packages:
	@if ! command -v mbpoll >/dev/null 2>&1 || ! command -v socat >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	    (apt-get update -qq >/dev/null 2>&1; DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mbpoll socat >/dev/null 2>&1) \
	      || echo "note: could not install mbpoll/socat; the tests that need them will be skipped"; \
	  else echo "note: mbpoll/socat missing and apt-get not usable; the tests that need them will be skipped"; fi; \
	fi
	@if ! command -v chromium >/dev/null 2>&1; then \
	  if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	    (apt-get update -qq >/dev/null 2>&1; DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null 2>&1) \
	      || echo "note: could not install chromium; the HTML report screenshots will be skipped"; \
	  else echo "note: chromium missing and apt-get not usable; the HTML report screenshots will be skipped"; fi; \
	fi

run: setup
	$(BIN)/shm run --force --out $(OUT)/run

# --durations: the thirty slowest tests end the log, so a suite that grows past ~15 minutes says where.
# --dist worksteal: a worker that runs dry takes half of the other's queue (with the default, one worker idled for
# minutes at the end while the other worked through its queue: 22 min wall for 27 min of CPU on two cores).
test: setup typecheck
	$(BIN)/ruff check .
	$(BIN)/lint-imports
	$(BIN)/pytest -n 2 --dist worksteal --timeout=600 --durations=30 -m "not realtime and not heavy"

# The long versions of behaviours `make test` covers with a smaller case (the whole library as candidates, the
# challenge's own records; minutes each when their compositions compile cold; docs/testing.md lists them).
test-slow: setup
	$(BIN)/pytest -n 2 --dist worksteal --timeout=1800 -m heavy

# The paced wall-clock fault matrix (board and stub on real clocks over pty/TCP/RTU): ~17 s of waiting per case.
# Best run with real-time priority: `chrt -f 10 make test-realtime` (docs/real-rig.md).
test-realtime: setup
	$(BIN)/pytest -n 2 --timeout=600 -m realtime -s

# Inner loop: unit and property tests only (no sockets, ptys, subprocesses or long end-to-end runs).
test-fast: setup
	$(BIN)/pytest -n 2 --dist worksteal --timeout=600 -m "not slow and not integration and not realtime and not heavy" -q

# Long property-based run over the command line (issue 15): many more valid inputs than `make test` draws, and
# `shm campaign` for every n = 1..500. Hypothesis keeps its example database in .cache/hypothesis (git-ignored),
# so a failure found once is replayed first next time. FUZZ_EXAMPLES sets the examples per property.
FUZZ_EXAMPLES ?= 50
fuzz: setup
	SHM_CLI_FUZZ=1 SHM_CLI_FUZZ_EXAMPLES=$(FUZZ_EXAMPLES) $(BIN)/pytest -n 2 --timeout=0 -q \
	  tests/shm_cli/test_cli_properties.py tests/shm_cli/test_cli_properties_campaign.py tests/shm_cli/test_cli_properties_json.py \
	  tests/studies/test_campaign_intervals.py

# Static types of every package (mypy; settings and the per-library exceptions in pyproject.toml [tool.mypy]).
typecheck: setup
	$(BIN)/mypy

lint: setup
	$(BIN)/ruff check .
	$(BIN)/lint-imports

# The bench extra (numbalsoda, a peer timed by bench_plant) needs gfortran and cmake. Never fatal: without it the
# peer is skipped with the reason printed.
bench-extra:
	@if ! $(BIN)/python -c "import numbalsoda" >/dev/null 2>&1; then \
	  if ! command -v gfortran >/dev/null 2>&1 || ! command -v cmake >/dev/null 2>&1; then \
	    if [ "$$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then \
	      (apt-get update -qq >/dev/null 2>&1; DEBIAN_FRONTEND=noninteractive apt-get install -y -qq gfortran cmake >/dev/null 2>&1) \
	        || echo "note: could not install gfortran/cmake; bench_plant will skip numbalsoda"; \
	    fi; \
	  fi; \
	  $(BIN)/pip install --quiet -e '.[bench]' >/dev/null 2>&1 \
	    || echo "note: could not install the bench extra (numbalsoda); bench_plant will skip it"; \
	fi

bench: setup bench-extra
	$(BIN)/python -m bench --out $(OUT)/bench

# Mutation check of the pure core (issue 18; docs/testing.md): incremental (mutmut's cache under out/mutate/work),
# 2 workers, table in out/mutate/; exits 1 below 95 % caught per module. MODULE=regimes for one module.
mutate: setup
	nice -n 10 $(BIN)/python mutation/mutate.py $(foreach m,$(MODULE),--module $(m))

clean:
	rm -rf $(VENV) .cache $(OUT) build *.egg-info
