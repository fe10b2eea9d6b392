# The two set-up commands. Both build .venv when it is missing and are quick when it exists.
# The ros-jazzy wheels are built for Python 3.11: prefer python3.11 when python3 is another.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
# A venv Python started from another ros-wheel Python must not inherit the bootstrap marker.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE
# Bytecode caches kept (they are ignored by git): with PYTHONDONTWRITEBYTECODE set, every
# pytest process compiles the suite and rewrites its asserts anew (twice the collection CPU).
unexport PYTHONDONTWRITEBYTECODE

.PHONY: demo test test-fast test-seconds lint mutation venv clean-venv system-deps

venv: $(VENV)/.stamp

$(VENV)/.stamp: pyproject.toml rv_te_bench/core/_lagrange.c rv_te_msgs_py/pyproject.toml rv_te_msgs_py/CMakeLists.txt $(wildcard rv_te_msgs_py/msg/*.msg rv_te_msgs_py/srv/*.srv rv_te_msgs_py/action/*.action)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet ./rv_te_msgs_py
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

demo: venv
	$(VENV)/bin/rv-te demo

# Tests run in parallel, by default one pytest-xdist worker more than the cores (each with a ROS
# domain of its own, tests/conftest.py), whole files per worker, the longest files first. The
# suite's files wait (subprocesses, nodes, a browser) 2.3x as long as they compute: on the
# 2-core VM, quiet, side by side on one tree (2026-11-27, 2,381 tests), two workers took
# 13 min 29 s (111 % CPU), three 10 min 24 s (143 % CPU) with no failure. TEST_WORKERS=1 runs
# the files one at a time.
TEST_WORKERS ?= $(shell echo $$(( $$(nproc 2>/dev/null || echo 1) + 1 )))
PYTEST_PAR   := $(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile

# The whole suite (PostgreSQL included, where installed: make system-deps).
test: venv
	$(PYTEST_PAR)

# The quick loop: every test that needs no ROS middleware and is not marked slow.
test-fast: venv
	$(PYTEST_PAR) -m "not ros and not slow"

# Rewrites the committed seconds per test file (tests/seconds_per_file.json, which orders the
# files longest-first where .pytest_cache has no times, as on CI's fresh clone) from the
# times the last `make test` kept in .pytest_cache, and lists the files taking most wall and
# CPU seconds. Run it after a full run on a quiet machine.
test-seconds:
	$(PY) scripts/test_seconds.py

# The house rules checked by tools: ruff's rule set ([tool.ruff.lint] in pyproject.toml), the
# layering contracts ([tool.importlinter]) and the type check ([tool.mypy]: its files).
lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports
	$(VENV)/bin/mypy

# Mutation testing of core/, acceptance/, store/ and io/importers/ ([tool.mutmut] in
# pyproject.toml; docs/TESTING.md has the score and the accepted survivors). Hours on two
# cores; not in CI. MUTANTS='rv_te_bench.acceptance*' runs a subset.
MUTANTS ?=
mutation: venv
	$(PY) -m pip install --quiet -e '.[mutation]'
	rm -rf mutants   # mutmut keeps copies of the sources there: results of an older tree
	$(VENV)/bin/mutmut run $(MUTANTS)
	$(VENV)/bin/mutmut results

clean-venv:
	rm -rf $(VENV)

# System packages the full test suite uses beyond Python: a PostgreSQL server for the results
# store tests (they start their own server), Debian's chromium + chromium-driver for the live
# page's and the unit report's browser tests (screen and print to PDF; without them those
# tests are skipped with the reason, except in CI).
# Needs root (or sudo); .ci/run calls it on the fresh CI machine.
APT_INSTALL = DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends
system-deps:
	@if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; then \
	  echo "chromium: present"; \
	elif [ "$$(id -u)" = 0 ]; then apt-get update -qq && $(APT_INSTALL) chromium chromium-driver \
	  >/dev/null && echo "chromium: installed"; \
	elif command -v sudo >/dev/null; then sudo apt-get update -qq && sudo $(APT_INSTALL) \
	  chromium chromium-driver >/dev/null && echo "chromium: installed"; \
	else echo "chromium: missing and cannot install (not root, no sudo)"; fi
	@if ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then echo "postgresql: present"; \
	elif [ "$$(id -u)" = 0 ]; then apt-get update -qq && DEBIAN_FRONTEND=noninteractive \
	  apt-get install -y -qq --no-install-recommends postgresql >/dev/null && echo "postgresql: installed"; \
	elif command -v sudo >/dev/null; then sudo apt-get update -qq && sudo DEBIAN_FRONTEND=noninteractive \
	  apt-get install -y -qq --no-install-recommends postgresql >/dev/null && echo "postgresql: installed"; \
	else echo "postgresql: missing and cannot install (not root, no sudo)"; fi
