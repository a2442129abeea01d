# The two commands of the README: `make demo` and `make test`.
# Both create .venv when it is missing and install flatfree with the extras they need.
# `make test` lints first (`make lint`: ruff with the rules of pyproject.toml [tool.ruff.lint]).
# The install is redone only when pyproject.toml changes (a stamp file per extra set).

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip

.PHONY: demo lint test bench clean-cache clean

# numba's on-disk cache does not notice when a compiled function that another module imports
# has changed (DESIGN.md "Speed by design"): `import flatfree` clears the package's cached
# functions whenever its sources changed (src/flatfree/_jitcache.py), for make and plain
# `python` / `pytest` runs alike. A NUMBA_CACHE_DIR of your own is yours to keep in step.

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

demo: $(VENV)/.installed
	$(VENV)/bin/flatfree demo

# ruff (a test extra) over the whole tree; any finding fails the target.
lint: $(VENV)/.installed-test
	$(VENV)/bin/ruff check .

# The HTML report's browser test needs headless Chromium (Debian packages): installed here when
# possible (root + apt-get), otherwise the test skips with a clear message.
test: $(VENV)/.installed-test lint
	bash tools/install_browser.sh
	$(PY) -m pytest -q

bench: $(VENV)/.installed-bench
	$(PY) benchmarks/run_all.py

# Clear numba's cache next to the sources (and .numba-cache/, where make kept it before).
clean-cache:
	find src -name '__pycache__' -type d -prune -exec rm -rf {} +
	rm -rf .numba-cache

clean: clean-cache
	rm -rf $(VENV) build *.egg-info src/*.egg-info
