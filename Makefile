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

# uv installs requirements.txt far faster than pip (the same pins; here it resolved every
# package under them as pip does). It copies from its cache rather than hard-linking, because
# devtools/patch_ros_cmake.py rewrites files of the venv in place. make INSTALLER=pip uses pip alone (for an
# index set in pip's configuration, which uv does not read).
INSTALLER ?= uv
$(if $(filter uv pip,$(INSTALLER)),,$(error INSTALLER must be uv or pip, not '$(INSTALLER)'))
UV_VERSION := 0.13.9
$(DEPS): requirements.txt | $(PY)
ifeq ($(INSTALLER),uv)
	$(PY) -m pip install --quiet --disable-pip-version-check uv==$(UV_VERSION)
	$(VENV)/bin/uv pip install --quiet --link-mode copy --python $(PY) -r requirements.txt
else
	$(PY) -m pip install --quiet --disable-pip-version-check -r requirements.txt
endif
	touch $@

# Editable installs: sources stay in src/; devtools/venv-scripts.cfg overrides the
# ROS-style script dir of setup.cfg so console scripts land in .venv/bin.
$(PKGS): $(DEPS) devtools/venv-scripts.cfg $(wildcard src/*/setup.py src/*/setup.cfg src/*/package.xml)
	DIST_EXTRA_CONFIG=$(CURDIR)/devtools/venv-scripts.cfg $(PY) -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation \
	    -e src/crane_msgs_py -e src/crane_sim -e src/crane_planner
	touch $@

# crane_interfaces (ament_cmake + rosidl): built with colcon, as a ROS workspace builds it, from scratch
# whenever an interface file changes, into the venv's ros/install/crane_interfaces (nothing outside the
# venv; test/ros/test_workspace.py builds the Python packages as an overlay on it). Nobody sources
# anything: a .pth file puts its Python package on sys.path, and a symlink
# site-packages/ros_crane_interfaces.libs -> its lib/ is where the ROS wheels' bootstrapper
# (ros_wheels_bootstrapper.pth, which re-executes Python with LD_LIBRARY_PATH set to the venv's lib/ and
# site-packages/ros_*.libs) finds it, as the type supports need.
# devtools/patch_ros_cmake.py first repoints the wheels' CMake files at this venv's headers.
IFACE := src/crane_interfaces
IFACE_FILES := $(IFACE)/package.xml $(IFACE)/CMakeLists.txt $(wildcard $(IFACE)/msg/*.msg $(IFACE)/srv/*.srv $(IFACE)/action/*.action)
ROS_WS := $(CURDIR)/$(VENV)/ros
IFACE_PREFIX := $(ROS_WS)/install/crane_interfaces
IFACE_LOG := $(ROS_WS)/build/crane_interfaces.log
IFACES := $(VENV)/.interfaces-installed
ROS_BUILD_ENV := AMENT_PREFIX_PATH=$(CURDIR)/$(VENV) CMAKE_PREFIX_PATH=$(CURDIR)/$(VENV)

$(IFACES): $(DEPS) devtools/patch_ros_cmake.py $(IFACE_FILES)
	$(PY) devtools/patch_ros_cmake.py
	rm -rf $(ROS_WS)/build $(ROS_WS)/install $(ROS_WS)/log $@
	@mkdir -p $(ROS_WS)/build
	@echo "building crane_interfaces with colcon (log: $(IFACE_LOG))"
	@$(ROS_BUILD_ENV) MAKEFLAGS=-j2 $(VENV)/bin/colcon --log-base $(ROS_WS)/log build --base-paths $(IFACE) \
	    --build-base $(ROS_WS)/build --install-base $(ROS_WS)/install \
	    --cmake-args -DPython3_EXECUTABLE=$(CURDIR)/$(PY) -DBUILD_TESTING=OFF > $(IFACE_LOG) 2>&1 \
	   || { tail -n 40 $(IFACE_LOG); tail -n 40 $(ROS_WS)/log/latest_build/crane_interfaces/stdout_stderr.log; exit 1; }
	@site=$$($(PY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))') \
	 && pkg=$$(cd $(IFACE_PREFIX) && ls -d lib/python3*/site-packages) \
	 && echo $(IFACE_PREFIX)/$$pkg > $$site/crane_interfaces.pth \
	 && ln -sfn $(IFACE_PREFIX)/lib $$site/ros_crane_interfaces.libs
	env -u _ROS_WHEELS_BOOTSTRAP_COMPLETE $(PY) -c 'from rclpy.serialization import serialize_message; \
	    from crane_interfaces.action import ExecuteMove; serialize_message(ExecuteMove.Feedback())'
	touch $@

# The bytecode (.pyc) of every package, written once here: where PYTHONDONTWRITEBYTECODE is set, as on some CI
# hosts, no process caches it, and each would compile rclpy, numpy, scipy and CasADi's Python again (an import
# of the planner's stack takes several times as long, at every node start: docs/benchmarks.md). The
# dependencies (uv writes none; pip's are skipped as up to date), this repository's packages (editable:
# imported from src/; an edited module is compiled again where it is imported, its .pyc only unused) and the
# interface package.
PYC := $(VENV)/.pyc-compiled
$(PYC): $(PKGS) $(IFACES) $(shell find src -name '*.py')
	$(PY) -m compileall -q -j 2 src $(ROS_WS)/install \
	    $$($(PY) -c 'import sysconfig; print(sysconfig.get_path("purelib"))')
	touch $@

install: $(PKGS) $(IFACES) $(PYC)

demo: install
	@mkdir -p $(OUT)
	$(VENV)/bin/crane-plan compare --displacement 0.3 --duration 3 --methods nvf,rvf,zv,nzv,zvd --plot $(OUT)/compare.png
	$(VENV)/bin/crane-demo --out $(OUT)

# The linter first: a finding fails the suite before any test runs (ruff.toml says which rules).
# Two workers: one runs the real-time ROS tests in order (one node set at a time, real time, mostly waiting),
# the other the pure tests and the ROS tests that time nothing meanwhile, at a lower CPU priority
# (test/conftest.py).
test: lint
	$(PY) -m pytest -q -n 2 --dist loadgroup --durations=30 test

# Every test that starts no ROS node (pytest marker ros, see test/conftest.py); docs/testing.md has its time.
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
