# Two commands set everything up on a fresh machine:
#   make test   create .venv, install the project with its test extras, check the import layers and lint, run the tests
#   make demo   same set-up, then run the main job
#   make docs   build the documentation site (mkdocs, into site/) with --strict
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: test test-slow demo bench docs clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

test: $(STAMP)  # the import layers and the lint rules first (seconds), then the tests
	$(VENV)/bin/lint-imports
	$(VENV)/bin/ruff check .
	$(PY) -m pytest -q -n 2

test-slow: $(STAMP)  # the checks marked slow (coverage Monte Carlo, coupled wrist, clusters of processes…)
	$(PY) -m pytest -q -m slow || [ $$? -eq 5 ]

demo: $(STAMP)
	$(VENV)/bin/oed demo

DOCS_STAMP := $(VENV)/.installed-docs

$(DOCS_STAMP): $(STAMP) pyproject.toml
	$(PY) -m pip install --quiet -e '.[docs]'
	touch $(DOCS_STAMP)

docs: $(DOCS_STAMP)  # the reference site from docs/ and mkdocs.yml; any warning fails the build
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict

bench: $(STAMP)
	for script in benchmarks/bench_*.py; do $(PY) $$script || exit 1; done

clean:
	rm -rf $(VENV) build site *.egg-info
