# Set-up, demo and tests. `make demo` and `make test` each create or refresh .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: demo test venv release notebooks benchmark clean

$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e .
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(PY) -m course demo

test: $(STAMP)
	$(PY) -m pytest -q

release: $(STAMP)
	$(PY) -m course release

notebooks: $(STAMP)
	$(PY) -m notebooks.build --execute

benchmark: $(STAMP)
	$(PY) -m course benchmark

clean:
	rm -rf $(VENV) out *.egg-info
