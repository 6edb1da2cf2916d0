# microfab: `make run` runs the default job on the digital twin and writes report/msl-ilc/
# (every default output has its own folder under report/, which `make clean` removes);
# `make test` runs the test suite. Both create .venv and install everything first.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: install run test test-kernel fuzz bench lint clean shipped-models

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip "setuptools>=68" wheel
	# the CPU build of PyTorch, pinned here (any other torch pulls the CUDA packages)
	$(BIN)/python -m pip install -q torch==2.13.0
	$(BIN)/python -m pip install -q -e ".[dev,all]"
	touch $(STAMP)

install: $(STAMP)

run: $(STAMP)
	$(BIN)/microfab run

test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2

# the suite again on a second BLAS code path, one thread per worker, PyTorch's baseline CPU
# kernels: a check that holds only on the kernels that recorded it shows up here (CI runs it)
KERNEL ?= SandyBridge
test-kernel: $(STAMP)
	OPENBLAS_CORETYPE=$(KERNEL) OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 \
	ATEN_CPU_CAPABILITY=default $(BIN)/python -m pytest -q -n 2 -p no:cacheprovider

# 10 000 generated bad (and some good) inputs through every command that reads a file or
# parameters; prints the table and fails on a traceback, a hang, or an untidy refusal
fuzz: $(STAMP)
	$(BIN)/python tests/fuzz/run_fuzz.py --cases 14000

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_cli.py
	$(BIN)/python benchmarks/bench_sim.py
	$(BIN)/python benchmarks/bench_dxf.py
	$(BIN)/python benchmarks/bench_drawings.py
	$(BIN)/python benchmarks/bench_topp.py
	$(BIN)/python benchmarks/bench_droplet.py
	$(BIN)/python benchmarks/bench_sweep.py
	$(BIN)/python benchmarks/bench_nanomanipulator.py
	$(BIN)/python benchmarks/bench_laser.py
	$(BIN)/python benchmarks/bench_contour_error.py
	$(BIN)/python benchmarks/bench_slm.py
	$(BIN)/python benchmarks/bench_identify.py
	$(BIN)/python benchmarks/bench_ann.py
	$(BIN)/python benchmarks/bench_optimize.py --plain-cpu 120

# retrain the models shipped for the built-in XY stage twin (seed 002; a few minutes on
# 2 cores) into src/microfab/data/xy_stage_models, with their record trained.json
shipped-models: $(STAMP)
	$(BIN)/python -m microfab.experiments.seed002_stage.shipped

lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks examples
	$(BIN)/ruff format --check src tests benchmarks examples
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) report build *.egg-info
