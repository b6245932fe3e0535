# One-command entry points (see README.md). Everything is installed into .venv by these targets.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
DOCS_STAMP := $(VENV)/.installed-docs
LINT_STAMP := $(VENV)/.installed-lint
# The versions the test suite was last run with (make constraints re-resolves them): a fresh clone gets these
CONSTRAINTS := constraints.txt
# pytest-xdist workers: both cores by default (make test JOBS=1 for one process)
JOBS ?= 2

.PHONY: setup run test test-fast test-under-load lint bench bench-gpu docs constraints clean

$(STAMP): pyproject.toml $(CONSTRAINTS)
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e '.[test]'
	@# ExifTool (Debian's libimage-exiftool-perl) for the DNG NoiseProfile check; optional: its test skips without it
	@command -v exiftool >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
		timeout 180 apt-get install -y -qq --no-install-recommends libimage-exiftool-perl >/dev/null 2>&1; } || \
		echo "ExifTool not installed (apt-get install libimage-exiftool-perl): its DNG check will skip"
	touch $(STAMP)

setup: $(STAMP)

## Set up, then render the default scene (26 illuminants × 3 intensity factors) into outputs/macbeth_26/
run: $(STAMP)
	$(BIN)/camsim render scenes/macbeth_26.toml

## Set up, then run the test suite (Hypothesis's ci profile)
test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(JOBS)

## Set up, then run the test suite without the tests marked slow, with a fifth of the Hypothesis examples (dev)
test-fast: $(STAMP)
	HYPOTHESIS_PROFILE=dev $(BIN)/python -m pytest -q -n $(JOBS) -m "not slow"

## Set up, then run make test with one CPU-bound burner per core (BURNERS=N): it must pass on a busy machine too
test-under-load: $(STAMP)
	tools/test_under_load.sh

# The lint extra (ruff), on top of the set-up
$(LINT_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e '.[lint]'
	touch $(LINT_STAMP)

## Set up, then check the code with ruff: pyflakes, import order, lines of at most 120 ([tool.ruff] in pyproject.toml)
lint: $(LINT_STAMP)
	$(BIN)/ruff check camsim tests tools docs

# The docs extra (Sphinx and its extensions), on top of the set-up
$(DOCS_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e '.[docs]'
	touch $(DOCS_STAMP)

## Set up, then build the documentation into docs/_build/html/ (warnings are errors; the gallery's scripts run)
## and check that every internal link of the built pages resolves
docs: $(DOCS_STAMP)
	$(BIN)/python -m sphinx -W --keep-going -j $(JOBS) -b html docs docs/_build/html
	$(BIN)/python tools/check_docs_links.py docs/_build/html

## Set up, then run the W1 speed/memory benchmark (prints a JSON line last)
bench: $(STAMP)
	$(BIN)/python tools/bench_w1.py

## Set up, then run the GPU benchmark (prints a JSON line last; CPU figures only without a GPU)
bench-gpu: $(STAMP)
	$(BIN)/python tools/bench_gpu.py

## Re-resolve constraints.txt: the newest versions pyproject.toml's bounds allow, in a scratch venv (then make test)
constraints:
	rm -rf .venv-resolve
	$(PYTHON) -m venv .venv-resolve
	.venv-resolve/bin/python -m pip install --quiet --upgrade pip
	.venv-resolve/bin/python -m pip install --quiet '.[test,docs,lint]'
	{ echo "# The versions camsim's test suite was run with, on $$($(PYTHON) --version); made by make constraints."; \
	  echo "# make installs with pip -c constraints.txt; pyproject.toml's bounds say what camsim supports."; \
	  .venv-resolve/bin/python -m pip freeze --all | grep -v -E '^(pip|camsim-lowlight)[= @]'; } > $(CONSTRAINTS)
	rm -rf .venv-resolve build

clean:
	rm -rf $(VENV) outputs/macbeth_26 docs/_build docs/auto_examples docs/reference/generated docs/sg_execution_times.rst
