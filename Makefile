# Set-up and checks. `make demo` and `make test` are all a fresh machine needs (python3 >= 3.10).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# The PyTorch this repository is tested with, installed before the package: the CPU build (a plain `torch`
# would pull a multi-GB CUDA build). The package's [rl] extra asks only for a range (pyproject.toml).
# [video] (moviepy 1.x, for RecordVideo) is installed here so that its test runs (pyproject.toml: why 1.x).
TORCH_PIN := torch==2.13.0

.PHONY: install test demo clean

install: $(STAMP)

# Re-installs only when pyproject.toml changes (editable install: code edits need no re-install). The last step
# compiles the Numba kernels into their on-disk cache (a 1.5 s burst at 150 rpm: ~70 s on this 2-core machine), as
# building a compiled extension would, so that the first `make demo` or test run does not spend that time.
$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --upgrade pip
	$(BIN)/python -m pip install $(TORCH_PIN)
	$(BIN)/python -m pip install -e ".[test,rl,video]"
	OPENBLAS_NUM_THREADS=1 $(BIN)/flagellum simulate --omega-rpm 150 --duration 1.5 --no-progress --out $(VENV)/compile-kernels
	touch $(STAMP)

test: install
	OPENBLAS_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 --durations=10

# The paper's rule-based planner and the adaptive planner with the line weight (the same planner correcting its
# turn map online from what the swimmer does and choosing turns that end near the path's line) steer the swimmer
# around the paper's 0.25 m square (the default preset, faithful), side by side (one worker process each):
# out/demo/summary.json, path.png (target vs achieved) and omega.png (the control signal).
demo: install
	OPENBLAS_NUM_THREADS=1 $(BIN)/flagellum follow --path square --controller rule --controller adaptive@line=2 --out out/demo

clean:
	rm -rf $(VENV) out build *.egg-info .pytest_cache
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
