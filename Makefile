# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
# Everything installs into .venv from requirements.txt (PyPI only, pinned):
# the ROS 2 wheels only work inside a virtual environment.
# The compiled ROS 2 wheels are built for CPython 3.11 only: the venv needs a Python 3.11,
# found as python3.11, else python3 if it is 3.11; or given with PYTHON=/path/to/python3.11.
PYTHON ?= $(firstword $(foreach p,python3.11 python3,$(if $(shell $(p) -c 'import sys; print(sys.version_info[:2] == (3, 11))' 2>/dev/null | grep True),$(p))))
VENV := .venv
PY := $(VENV)/bin/python
DEPS := $(VENV)/.deps-installed
PKGS := $(VENV)/.pkgs-installed
OUT ?= out

# Without a venv, stop at once (one line, exit 2) unless a Python 3.11 is at hand.
ifeq ($(wildcard $(PY)),)
ifneq ($(filter-out clean distclean,$(or $(MAKECMDGOALS),all)),)
ifneq ($(shell $(PYTHON) -c 'import sys; print(sys.version_info[:2] == (3, 11))' 2>/dev/null),True)
$(error the ROS 2 wheels (ros-jazzy-*) need Python 3.11, $(if $(PYTHON),and $(PYTHON) is not 3.11,and neither python3.11 nor python3 is 3.11): install one and run make PYTHON=/path/to/python3.11)
endif
endif
endif

.PHONY: all install demo test test-pure lint bench clean distclean
all: install

$(PY):
	$(PYTHON) -m venv $(VENV)

$(DEPS): requirements.txt | $(PY)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	touch $@

# Editable installs: sources stay in src/; devtools/venv-scripts.cfg overrides the
# ROS-style script dir of setup.cfg so console scripts land in .venv/bin.
$(PKGS): $(DEPS) devtools/venv-scripts.cfg $(wildcard src/*/setup.py src/*/setup.cfg src/*/package.xml)
	DIST_EXTRA_CONFIG=$(CURDIR)/devtools/venv-scripts.cfg $(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
	    -e src/crane_msgs_py -e src/crane_sim -e src/crane_planner
	touch $@

install: $(PKGS)

demo: install
	@mkdir -p $(OUT)
	$(VENV)/bin/crane-plan compare --displacement 0.3 --duration 3 --methods nvf,rvf,zv,nzv,zvd --plot $(OUT)/compare.png
	$(VENV)/bin/crane-demo --out $(OUT)

# The linter first: a finding fails the suite before any test runs (ruff.toml says which rules).
test: lint
	$(PY) -m pytest -q test

# Every test that starts no ROS node (pytest marker ros, see test/conftest.py): under 2 minutes.
test-pure: install
	$(PY) -m pytest -q -m "not ros" test

lint: install
	$(VENV)/bin/ruff check .

bench: install
	@mkdir -p $(OUT)
	$(PY) bench/run_all.py --out $(OUT)/bench.json

clean:
	rm -rf $(OUT) build install log .pytest_cache

distclean: clean
	rm -rf $(VENV)
