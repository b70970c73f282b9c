# Two commands for a fresh machine: `make demo` and `make test`.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python

.PHONY: setup demo test bench-data bench-model train evaluate clean

$(VENV)/.installed: requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	touch $@

setup: $(VENV)/.installed

demo: setup
	$(PY) -m model_runtime.data stats ../shared/mocap

test: setup
	$(PY) -m pytest -q

bench-data: setup
	PYTHONPATH=. $(PY) benchmarks/load_data.py

bench-model: setup
	PYTHONPATH=. $(PY) benchmarks/inference.py

train: setup
	$(PY) -m model_runtime.train

evaluate: setup
	$(PY) -m model_runtime.evaluate --json evaluation.json

clean:
	rm -rf $(VENV) .pytest_cache
