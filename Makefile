# Quick start: `make demo` runs the paper's scene and plots it, `make test` runs the tests.
# Both create .venv and install the package (with the test and plot extras) on first use.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
DEVICE ?=
DEMO_OUT ?= demo-output

.PHONY: demo test test-all lint format bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test,plot]'
	touch $(STAMP)

# the paper's sweep in vacuum and in sea-level air, and one shot of 100,000 pellets; then Tables 1-3
# in vacuum, Table 3 of both side by side, and the plots of all three (their paths)
SWEEP := --param surfaces.0.mu_s=0:0.5:0.05 --tie surfaces.0.mu_d=0.9* --overwrite $(if $(DEVICE),--device $(DEVICE),)
WR := $(VENV)/bin/warp-ricochet

demo: $(STAMP)
	mkdir -p $(DEMO_OUT)
	$(WR) sweep examples/paper.toml $(SWEEP) -o $(DEMO_OUT)/paper-sweep.h5 > /dev/null
	$(WR) sweep examples/paper.toml $(SWEEP) --set air.density=1.225 -o $(DEMO_OUT)/paper-sweep-air.h5 > /dev/null
	$(WR) run examples/paper.toml --set shot.count=100000 --overwrite $(if $(DEVICE),--device $(DEVICE),) \
	    -o $(DEMO_OUT)/paper-shot.h5 > /dev/null
	$(WR) report $(DEMO_OUT)/paper-sweep.h5
	$(WR) report $(DEMO_OUT)/paper-sweep.h5 $(DEMO_OUT)/paper-sweep-air.h5
	$(WR) plot $(DEMO_OUT)/paper-shot.h5 $(DEMO_OUT)/paper-sweep.h5 $(DEMO_OUT)/paper-sweep-air.h5 \
	    -o $(DEMO_OUT)/plots --overwrite

# lint and format check (ruff, pinned in the test extra) first: CI fails on either
test: lint
	$(PY) -m pytest -n 2 -q -m "not slow"

# every test, the slow ones of tests/slow.txt too (run before each stop; about 20 min on 2 cores)
test-all: lint
	$(PY) -m pytest -n 2 -q

lint: $(STAMP)
	$(PY) -m ruff check .
	$(PY) -m ruff format --check .

format: $(STAMP)
	$(PY) -m ruff check --fix .
	$(PY) -m ruff format .

bench: $(STAMP)
	$(PY) -m bench all $(if $(DEVICE),--device $(DEVICE),)

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .hypothesis
