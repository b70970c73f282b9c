# Two commands for a fresh machine: `make demo` and `make test`.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python

.PHONY: setup demo test bench-data bench-model bench-blender bench-scale bench-quality package train train-sampler evaluate clean

$(VENV)/.installed: requirements.txt
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -r requirements.txt
	touch $@

setup: $(VENV)/.installed

demo: setup
	$(PY) scripts/demo.py

test: setup
	$(PY) -m pytest -q

bench-data: setup
	PYTHONPATH=. $(PY) benchmarks/load_data.py

bench-model: setup
	PYTHONPATH=. $(PY) benchmarks/inference.py

bench-blender: setup
	$(PY) benchmarks/blender_generate.py

bench-scale: setup
	$(PY) benchmarks/blender_scale.py

bench-quality: setup
	$(PY) benchmarks/quality.py

# The extension zip, built and validated by Blender's own tool (out/trajevae-VERSION.zip).
BLENDER_EXT = $(VENV)/lib/python3.11/site-packages/bpy/5.0/scripts/addons_core/bl_pkg/cli/blender_ext.py
package: setup
	mkdir -p out
	$(PY) $(BLENDER_EXT) build --source-dir . --output-dir out
	$(PY) $(BLENDER_EXT) validate out/trajevae-*.zip

# The whole training, model then sampler (resumable: re-run to continue from the checkpoints).
train: setup
	$(PY) -m model_runtime.train
	$(PY) -m model_runtime.train_sampler

train-sampler: setup
	$(PY) -m model_runtime.train_sampler

evaluate: setup
	$(PY) -m model_runtime.evaluate --json evaluation.json

clean:
	rm -rf $(VENV) .pytest_cache
