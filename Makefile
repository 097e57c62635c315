# Two commands do all set-up on a fresh machine: `make demo` and `make test`.
# Everything installs into .venv from requirements.txt (PyPI only, pinned):
# the ROS 2 wheels only work inside a virtual environment.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
DEPS := $(VENV)/.deps-installed
PKGS := $(VENV)/.pkgs-installed
OUT ?= out

.PHONY: all install demo test bench clean distclean
all: install

$(PY):
	$(PYTHON) -m venv $(VENV)

$(DEPS): requirements.txt | $(PY)
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
	touch $@

# Editable installs: sources stay in src/; tools/venv-scripts.cfg overrides the
# ROS-style script dir of setup.cfg so console scripts land in .venv/bin.
$(PKGS): $(DEPS) tools/venv-scripts.cfg $(wildcard src/*/setup.py src/*/setup.cfg src/*/package.xml)
	DIST_EXTRA_CONFIG=$(CURDIR)/tools/venv-scripts.cfg $(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
	    -e src/crane_msgs_py -e src/crane_sim -e src/crane_planner
	touch $@

install: $(PKGS)

demo: install
	@mkdir -p $(OUT)
	$(VENV)/bin/crane-plan compare --displacement 0.3 --duration 3 --methods nvf,rvf,zv,nzv,zvd --plot $(OUT)/compare.png
	$(VENV)/bin/crane-demo --out $(OUT)

test: install
	$(PY) -m pytest -q test

bench: install
	@mkdir -p $(OUT)
	$(PY) bench/run_all.py --out $(OUT)/bench.json

clean:
	rm -rf $(OUT) build install log .pytest_cache

distclean: clean
	rm -rf $(VENV)
