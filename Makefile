# One-command entry points (see README.md). Everything is installed into .venv by these targets.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup run test test-fast bench bench-gpu clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	@# ExifTool (Debian's libimage-exiftool-perl) for the DNG NoiseProfile check; optional: its test skips without it
	@command -v exiftool >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
		timeout 180 apt-get install -y -qq --no-install-recommends libimage-exiftool-perl >/dev/null 2>&1; } || \
		echo "ExifTool not installed (apt-get install libimage-exiftool-perl): its DNG check will skip"
	touch $(STAMP)

setup: $(STAMP)

## Set up, then render the default scene (26 illuminants × 3 intensity factors) into outputs/macbeth_26/
run: $(STAMP)
	$(BIN)/camsim render scenes/macbeth_26.toml

## Set up, then run the test suite
test: $(STAMP)
	$(BIN)/python -m pytest -q

## Set up, then run the test suite without the tests marked slow (about a quarter of the time)
test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -m "not slow"

## Set up, then run the W1 speed/memory benchmark (prints a JSON line last)
bench: $(STAMP)
	$(BIN)/python tools/bench_w1.py

## Set up, then run the GPU benchmark (prints a JSON line last; CPU figures only without a GPU)
bench-gpu: $(STAMP)
	$(BIN)/python tools/bench_gpu.py

clean:
	rm -rf $(VENV) outputs/macbeth_26
