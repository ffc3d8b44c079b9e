# Quick start: `make demo` runs the paper's scene, `make test` runs the tests.
# Both create .venv and install the package on first use.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
DEVICE ?=
DEMO_OUT ?= demo-output

.PHONY: demo test bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

# the paper's sweep in vacuum (Tables 1-3), then in sea-level air, then Table 3 of both side by side
SWEEP := --param surfaces.0.mu_s=0:0.5:0.05 --tie surfaces.0.mu_d=0.9* --overwrite $(if $(DEVICE),--device $(DEVICE),)

demo: $(STAMP)
	mkdir -p $(DEMO_OUT)
	$(VENV)/bin/warp-ricochet sweep examples/paper.toml $(SWEEP) -o $(DEMO_OUT)/paper-sweep.h5
	$(VENV)/bin/warp-ricochet sweep examples/paper.toml $(SWEEP) --set air.density=1.225 \
	    -o $(DEMO_OUT)/paper-sweep-air.h5 > /dev/null
	$(VENV)/bin/warp-ricochet report $(DEMO_OUT)/paper-sweep.h5 $(DEMO_OUT)/paper-sweep-air.h5

test: $(STAMP)
	$(PY) -m pytest -n 2 -q

bench: $(STAMP)
	$(PY) -m bench all $(if $(DEVICE),--device $(DEVICE),)

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .hypothesis
