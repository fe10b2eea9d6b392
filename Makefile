# The two set-up commands. Both build .venv when it is missing and are quick when it exists.
# The ros-jazzy wheels are built for Python 3.11: prefer python3.11 when python3 is another.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
PY     := $(VENV)/bin/python
# A venv Python started from another ros-wheel Python must not inherit the bootstrap marker.
unexport _ROS_WHEELS_BOOTSTRAP_COMPLETE

.PHONY: demo test lint venv clean-venv system-deps

venv: $(VENV)/.stamp

$(VENV)/.stamp: pyproject.toml setup.py rv_te_bench/core/_lagrange.c rv_te_msgs_py/pyproject.toml rv_te_msgs_py/CMakeLists.txt $(wildcard rv_te_msgs_py/msg/*.msg rv_te_msgs_py/srv/*.srv rv_te_msgs_py/action/*.action)
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet ./rv_te_msgs_py
	$(PY) -m pip install --quiet -e '.[test]'
	touch $@

demo: venv
	$(VENV)/bin/rv-te demo

test: venv
	$(PY) -m pytest -q

# The house rules checked by tools: ruff's rule set ([tool.ruff.lint] in pyproject.toml) and
# the layering contracts ([tool.importlinter]).
lint: venv
	$(VENV)/bin/ruff check .
	$(VENV)/bin/lint-imports

clean-venv:
	rm -rf $(VENV)

# System packages the full test suite uses beyond Python: a PostgreSQL server for the results
# store tests (they start their own server), Debian's chromium + chromium-driver for the live
# page's browser tests (without them those tests are skipped with the reason, except in CI).
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
