# rsmcheck: `make test` runs everything CI runs; `make report` writes out/report.html.
# The virtual environment lives in .venv and is (re)installed from pyproject.toml.

PYTHON ?= python3
VENV := .venv
VPY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
PYTEST_ARGS ?=
# Re-install when pyproject.toml changes or a top-level package appears (the editable
# install maps the packages that exist when it runs).
PACKAGE_INITS := $(wildcard rsmcheck/__init__.py reference_model/__init__.py \
	exudyn_model/__init__.py pinocchio_check/__init__.py report/__init__.py)

.PHONY: venv test study report fullcheck faults clean

venv: $(STAMP)

$(STAMP): pyproject.toml $(PACKAGE_INITS)
	test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install -e '.[all,test]'
	touch $(STAMP)

# pytest exit code 5 = no tests collected: make fails (as for any non-zero code) and says why.
# Everything but the `study` tests (Exudyn at microsecond steps, tens of minutes: `make study`).
test: venv
	@status=0; $(VPY) -m pytest -m "not study" $(PYTEST_ARGS) || status=$$?; \
	if [ $$status -eq 5 ]; then echo "make test: FAILED: pytest collected no tests (exit 5)" >&2; \
	elif [ $$status -ne 0 ]; then echo "make test: FAILED: pytest exited with $$status" >&2; fi; \
	exit $$status

study: venv
	$(VPY) -m pytest -m study $(PYTEST_ARGS)

# Fault injection (docs/gate.md): ~23 plausible bugs, each in a copy of the tree, on every
# case and the chained short mission; which checks catch which on which case.  Not in CI
# (≈ 50 min on 2 idle cores); writes docs/data/faults.json.
faults: venv
	$(VPY) -m rsmcheck.orchestration.faults

# The short variants of every case and the short mission, both engines side by side
# (rsmcheck.orchestration.collect stores the runs in out/; a second `make report` re-renders in seconds
# and re-runs only what the code or the case files changed).
report: venv
	$(VENV)/bin/rsmcheck report --short --out out/report.html

# The slow tier, not in CI: every case and the whole mission (p1 → p5, chained) at full
# length in both engines, compared with the cases' tolerances.  80–82 min on 2 cores (2026-11-26).
fullcheck: venv
	$(VENV)/bin/rsmcheck report --out out/full/report.html

clean:
	rm -rf out build *.egg-info .pytest_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +
