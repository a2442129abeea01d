# The two commands of the README: `make demo` and `make test`.
# Both create .venv when it is missing and install flatfree with the extras they need.
# The install is redone only when pyproject.toml changes (a stamp file per extra set).

PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip

.PHONY: demo test bench clean-cache clean

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

# The HTML report's browser test needs headless Chromium (Debian packages): installed here when
# possible (root + apt-get), otherwise the test skips with a clear message.
test: $(VENV)/.installed-test
	bash tools/install_browser.sh
	$(PY) -m pytest -q

bench: $(VENV)/.installed-bench
	$(PY) benchmarks/run_all.py

# numba's on-disk cache does not notice when an imported compiled function changed:
# clear it whenever results surprise you (DESIGN.md, "Speed by design").
clean-cache:
	find src -name '__pycache__' -type d -prune -exec rm -rf {} +

clean: clean-cache
	rm -rf $(VENV) build *.egg-info src/*.egg-info
