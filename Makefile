# amb-rig: two commands set everything up (`make demo`, `make test`); see README.md.
SHELL := /bin/bash
PYTHON ?= python3.11
VENV := .venv
BIN := $(CURDIR)/$(VENV)/bin
REF_VENV := .venv-ref

# DDS stays on this machine: localhost-only discovery and a domain id per make invocation.
# (The test session picks and locks its own id in tests/conftest.py.)
export ROS_AUTOMATIC_DISCOVERY_RANGE := LOCALHOST
unexport ROS_STATIC_PEERS
ROS_DOMAIN_ID ?= $(shell $(PYTHON) -c "import random; print(random.randint(10, 99))")
export ROS_DOMAIN_ID
export AMENT_PREFIX_PATH := $(CURDIR)/$(VENV)
export MPLBACKEND := Agg
export PYTHONDONTWRITEBYTECODE := 1
export OPENBLAS_NUM_THREADS ?= 1

PKGS := amb_dynamics amb_ros base_motion amb_plant amb_controller stability_monitor amb_bag amb_bringup
PKG_SETUPS := $(foreach p,$(PKGS),src/$(p)/setup.py)

.PHONY: demo test bench lint format venv ref clean chromium

$(VENV)/.installed: requirements.txt $(PKG_SETUPS)
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q -r requirements.txt
	$(BIN)/python -m pip install -q --no-deps $(foreach p,$(PKGS),-e src/$(p))
	@touch $@

$(REF_VENV)/.installed: requirements-ref.txt
	@test -x $(REF_VENV)/bin/python || $(PYTHON) -m venv $(REF_VENV)
	$(REF_VENV)/bin/python -m pip install -q -r requirements-ref.txt
	@touch $@

venv: $(VENV)/.installed
ref: $(REF_VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/python tools/demo.py

test: $(VENV)/.installed $(REF_VENV)/.installed chromium
	$(BIN)/python -m pytest

# the commissioning report's render test opens it in Debian's headless Chromium (these machines run as root)
chromium:
	@command -v chromium >/dev/null || { apt-get update -qq && \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null; } || \
	  echo "make: could not install chromium (apt-get as root): tests/test_report.py will say so"

bench: $(VENV)/.installed
	$(BIN)/python benchmarks/run_all.py

lint: $(VENV)/.installed
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .

format: $(VENV)/.installed
	$(BIN)/ruff format .
	$(BIN)/ruff check --fix .

clean:
	rm -rf $(VENV) $(REF_VENV) out build install log .pytest_cache .ruff_cache
