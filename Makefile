# Set-up, demo and tests. `make demo` and `make test` each create or refresh .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test test-fast lint venv release notebooks benchmark clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev,peers]"
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(PY) -m course demo

lint: $(STAMP)
	$(PY) -m ruff check .
	$(PY) -m mypy course autograder
	$(VENV)/bin/lint-imports

# everything: lint, type check and the whole suite (what CI runs), on every core: a test file
# stays on one worker (its module-scoped batch gradings run once); the ten slowest are listed
test: lint
	$(PY) -m pytest -q -n auto --dist loadfile --durations=10

# the quick loop while working: lint and the tests not marked slow
test-fast: lint
	$(PY) -m pytest -q -m "not slow" -n auto --dist loadfile

release: $(STAMP)
	$(PY) -m course release

notebooks: $(STAMP)
	$(PY) -m notebooks.build --execute

# the course as a static website in out/site/html (docs/site.md): every lesson executed in a student tree, in
# its quick setting (minutes; without --small the full setting takes an hour or more on two cores)
.PHONY: site
site: $(STAMP)
	$(PY) -m pip install --quiet -e ".[site]"
	$(PY) -m notebooks.site --small

benchmark: $(STAMP)
	$(PY) -m course benchmark

clean:
	rm -rf $(VENV) out *.egg-info

# the generated pages: docs/commands.md (every command's --help) and docs/measured.md (from docs/measured/)
.PHONY: docs-pages
docs-pages: $(STAMP)
	$(PY) -m course.app.commands_page
	$(PY) -m course.app.measured_page
