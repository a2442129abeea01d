# The two commands of the README: `make demo` and `make test`.
# Both create .venv when it is missing and install flatfree with the extras they need.
# `make test` lints first (`make lint`: ruff with the rules of pyproject.toml [tool.ruff.lint]).
# The install is redone only when pyproject.toml changes (a stamp file per extra set).

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip

.PHONY: demo lint test bench clean-cache clean numba-cache

# numba's on-disk cache does not notice when a compiled function that another module imports
# has changed (DESIGN.md "Speed by design"): a stale cache then runs old code silently. The make
# targets therefore keep one cache folder per state of the sources (a hash of src/**/*.py) and
# drop the folders of older states. (A plain `pytest` or `python` run uses numba's default
# cache next to the sources: `make clean-cache` clears both.)
SRC_HASH := $(shell find src -name '*.py' -type f | LC_ALL=C sort | xargs cat | sha1sum | cut -c1-12)
NUMBA_CACHE_ROOT := $(CURDIR)/.numba-cache
export NUMBA_CACHE_DIR := $(NUMBA_CACHE_ROOT)/$(SRC_HASH)

numba-cache:
	@mkdir -p $(NUMBA_CACHE_DIR)
	@find $(NUMBA_CACHE_ROOT) -mindepth 1 -maxdepth 1 ! -name $(SRC_HASH) -exec rm -rf {} +

$(PY):
	$(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip

$(VENV)/.installed-test: pyproject.toml | $(PY)
	$(PIP) install --quiet -e '.[test]'
	touch $@

$(VENV)/.installed-bench: pyproject.toml | $(PY)
	$(PIP) install --quiet -e '.[test,bench]'
	touch $@

$(VENV)/.installed: pyproject.toml | $(PY)
	$(PIP) install --quiet -e .
	touch $@

demo: $(VENV)/.installed numba-cache
	$(VENV)/bin/flatfree demo

# ruff (a test extra) over the whole tree; any finding fails the target.
lint: $(VENV)/.installed-test
	$(VENV)/bin/ruff check .

# The HTML report's browser test needs headless Chromium (Debian packages): installed here when
# possible (root + apt-get), otherwise the test skips with a clear message.
test: $(VENV)/.installed-test numba-cache lint
	bash tools/install_browser.sh
	$(PY) -m pytest -q

bench: $(VENV)/.installed-bench numba-cache
	$(PY) benchmarks/run_all.py

# Clear every numba cache (the per-source-state folders and the default ones next to the sources).
clean-cache:
	find src -name '__pycache__' -type d -prune -exec rm -rf {} +
	rm -rf $(NUMBA_CACHE_ROOT)

clean: clean-cache
	rm -rf $(VENV) build *.egg-info src/*.egg-info
