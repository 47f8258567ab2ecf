# rsmcheck: `make test` runs everything CI runs; `make report` writes out/report.html;
# `make docs` builds the documentation site into out/site.
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

.PHONY: venv test study report fullcheck faults fuzz docs docs-vendor clean

venv: $(STAMP)

$(STAMP): pyproject.toml $(PACKAGE_INITS)
	test -x $(VPY) || $(PYTHON) -m venv $(VENV)
	$(VPY) -m pip install -e '.[all,test,docs]'
	touch $(STAMP)

# pytest exit code 5 = no tests collected: make fails (as for any non-zero code) and says why.
# Everything but the `study` tests (Exudyn at microsecond steps, full-length events, two fuzz
# scenarios end to end, the installed wheel compiling afresh: tens of minutes, `make study`).
test: venv
	@status=0; $(VPY) -m pytest -m "not study" $(PYTEST_ARGS) || status=$$?; \
	if [ $$status -eq 5 ]; then echo "make test: FAILED: pytest collected no tests (exit 5)" >&2; \
	elif [ $$status -ne 0 ]; then echo "make test: FAILED: pytest exited with $$status" >&2; fi; \
	exit $$status

study: venv
	$(VPY) -m pytest -m study $(PYTEST_ARGS)

# Fault injection (docs/gate.md): plausible bugs, each in a copy of the tree, on every case
# and the chained short mission; which checks catch which on which case.  Not in CI (about
# 50 min on 2 idle cores); writes docs/data/faults.json.
faults: venv
	$(VPY) -m rsmcheck.orchestration.faults

# The short variants of every case and the short mission, both engines side by side
# (rsmcheck.orchestration.collect stores the runs in out/; a second `make report` re-renders in seconds
# and re-runs only what the code or the case files changed).
report: venv
	$(VENV)/bin/rsmcheck compile
	$(VENV)/bin/rsmcheck report --short --out out/report.html

# The slow tier, not in CI: every case and the whole mission (p1 → p5, chained) at full
# length in both engines, compared with the cases' tolerances (over an hour on 2 cores).
fullcheck: venv
	$(VENV)/bin/rsmcheck compile
	$(VENV)/bin/rsmcheck report --out out/full/report.html

# The randomized cross-check's campaign of record (docs/fuzz.md), not in CI: FUZZ_N scenarios
# of seed FUZZ_SEED, both engines at two resolutions (about an hour on 2 cores for 100;
# --scheduler or $$RSMCHECK_SCHEDULER sends the runs to a cluster).  The scenarios and the
# failing case files go to out/fuzz/, the document to docs/data/fuzz.json.
FUZZ_N ?= 100
FUZZ_SEED ?= 2026
fuzz: venv
	@rm -f out/fuzz/fuzz.json; status=0; $(VENV)/bin/rsmcheck fuzz --n $(FUZZ_N) --seed $(FUZZ_SEED) --out out/fuzz || status=$$?; \
	if [ -f out/fuzz/fuzz.json ]; then cp out/fuzz/fuzz.json docs/data/fuzz.json.tmp && mv docs/data/fuzz.json.tmp docs/data/fuzz.json; fi; \
	exit $$status

# The documentation site (mkdocs.yml): docs/*.md, the API pages from the docstrings and the
# equations, rendered by the KaTeX files the site serves itself; --strict turns every
# warning (a broken link, a docstring griffe cannot read) into a failure, as in
# tests/docs/test_site.py.  Open out/site/index.html in a browser, no server needed.
docs: venv
	NO_MKDOCS_2_WARNING=1 $(VPY) -m mkdocs build --strict -d out/site

# The two libraries the site serves itself (no CDN), vendored under docs/javascripts/ from
# their npm packages (npm pack): KaTeX, the equations' renderer (the minified script and
# stylesheet, the licence and the woff2 fonts; the stylesheet's woff and ttf fallbacks
# are cut, so that it names only files the site has: every browser that runs the site
# reads woff2), and iframe-worker's shim, with which Material's offline plugin runs the
# search from file://.  Run it to change a version, then commit docs/javascripts/.
KATEX_VERSION := 0.19.1
IFRAME_WORKER_VERSION := 1.0.4
JS_DIR := docs/javascripts
docs-vendor:
	rm -rf out/vendor $(JS_DIR)/katex $(JS_DIR)/iframe-worker
	mkdir -p out/vendor $(JS_DIR)/katex/fonts $(JS_DIR)/iframe-worker
	cd out/vendor && npm pack --silent katex@$(KATEX_VERSION) iframe-worker@$(IFRAME_WORKER_VERSION) >/dev/null
	cd out/vendor && mkdir katex iframe-worker && tar xzf katex-$(KATEX_VERSION).tgz -C katex \
		&& tar xzf iframe-worker-$(IFRAME_WORKER_VERSION).tgz -C iframe-worker
	cp out/vendor/katex/package/LICENSE out/vendor/katex/package/dist/katex.min.js $(JS_DIR)/katex/
	cp out/vendor/katex/package/dist/fonts/*.woff2 $(JS_DIR)/katex/fonts/
	sed -E 's/,url\(fonts\/[^)]*\.(woff|ttf)\) format\("(woff|truetype)"\)//g' \
		out/vendor/katex/package/dist/katex.min.css > $(JS_DIR)/katex/katex.min.css
	cp out/vendor/iframe-worker/package/LICENSE $(JS_DIR)/iframe-worker/
	cp out/vendor/iframe-worker/package/shim/index.js $(JS_DIR)/iframe-worker/shim.js

clean:
	rm -rf out build *.egg-info .pytest_cache
	find . -path ./$(VENV) -prune -o -name __pycache__ -type d -prune -exec rm -rf {} +
