# Two commands on a fresh machine with Python 3.11+: `make sim` and `make test`.
# `make test` first installs the Debian packages the tests start (scripts/system-packages.sh),
# python3-venv among them when PYTHON is Debian's own Python without it; `make sim` installs
# nothing: when PYTHON cannot create .venv it stops at once, naming the package to install.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
EXAMPLE_PLUGIN := examples/umlbot_buzzer
TRACK  ?= models/tracks/s_bend.yaml
SPEED  ?= 10
OUT    ?= out

.PHONY: all install system-packages test lint typecheck pytest test-systemd web sim bench clean studio doc-images layout-cache

all: test

# The example plugin is installed as a package of its own: the tests use it from outside, as a
# user's plugin would be (tests/test_plugin_example.py).
$(STAMP): pyproject.toml $(EXAMPLE_PLUGIN)/pyproject.toml
	@$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "umlbot needs Python 3.11+, found " + sys.version.split()[0]'
	@PYTHON='$(PYTHON)' scripts/system-packages.sh --venv
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]' -e $(EXAMPLE_PLUGIN)
	@touch $@

install: $(STAMP)

system-packages:
	@PYTHON='$(PYTHON)' scripts/system-packages.sh

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/python scripts/check_layers.py

typecheck: $(STAMP)
	$(BIN)/mypy umlbot tests bench scripts $(EXAMPLE_PLUGIN)/umlbot_buzzer

pytest: system-packages $(STAMP)
	$(BIN)/pytest -m 'not systemd'

# The deploy units under a real systemd (tests/test_systemd_nspawn.py): Debian booted with
# systemd-nspawn, the car installed by deploy/install.sh. Needs root; skipped with the reason
# where the machine cannot run systemd-nspawn. The first run builds the Debian root with
# debootstrap (1-5 min, depending on the mirror) and caches it in ~/.cache/umlbot.
test-systemd: system-packages $(STAMP)
	$(BIN)/pytest -m systemd -s tests/test_systemd_nspawn.py

test: system-packages lint typecheck web pytest test-systemd

# The studio page's TypeScript: lint and format check (Biome), type check, unit tests (node --test),
# and the committed build in umlbot/studio/static must be what its sources build to (npm ci needs
# the npm registry).
WEB := umlbot/studio/web
web: system-packages
	cd $(WEB) && npm ci --no-audit --no-fund --loglevel=error && npm run --silent lint && npm run --silent check && npm test --silent
	@tmp=$$(mktemp -d) && trap 'rm -rf "$$tmp"' EXIT && (cd $(WEB) && node build.mjs --out "$$tmp" >/dev/null) \
		&& diff -r "$$tmp" umlbot/studio/static >/dev/null \
		|| { echo "umlbot/studio/static is not what $(WEB) builds to: run 'make studio' and commit it" >&2; exit 1; }

sim: $(STAMP)
	@mkdir -p $(OUT)
	$(BIN)/umlbot sim models/robot_car --track $(TRACK) --speed $(SPEED) --plot $(OUT)/sim.png

bench: $(STAMP)
	$(BIN)/python bench/rpc.py
	$(BIN)/python bench/compile.py
	$(BIN)/python bench/orchestrator.py
	$(BIN)/python bench/sim.py
	$(BIN)/python bench/studio.py
	$(BIN)/python bench/memory.py
	$(BIN)/python bench/chaos.py
	$(BIN)/python bench/record.py

# Rebuild the studio page from its sources (needs Node.js and npm; the built page is committed).
studio:
	cd $(WEB) && npm ci --no-audit --no-fund && npm run build

# The screenshots of docs/studio.md's tutorial, taken by doing its steps in a real page (Chromium).
doc-images: system-packages $(STAMP)
	$(BIN)/python scripts/studio_doc_images.py --out docs/images

# The layouts shipped beside the reference models (models/*/layout-cache.json, docs/studio.md
# "Layout cache"): laid out afresh by the page in Chromium; run it after a change of the layout code,
# of ELK or of a reference model (tests/test_studio_layout_cache_browser.py says when).
layout-cache: system-packages $(STAMP)
	$(BIN)/python scripts/layout_cache.py

clean:
	rm -rf $(VENV) $(OUT) .mypy_cache .ruff_cache .pytest_cache build *.egg-info
