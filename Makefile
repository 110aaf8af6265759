# Quick start: `make demo` and `make test`. Both create .venv and install everything they need.
PY      ?= python3
VENV    := .venv
BIN     := $(VENV)/bin
STAMP   := $(VENV)/.installed
DEMO_OUT ?= demo-output

.PHONY: demo test lint bench clean sysdeps

# open3d links against libusb, and the report test drives a headless chromium: install them
# from Debian when they are missing (needs root, as here).
sysdeps:
	@if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then \
	  echo "installing libusb-1.0-0 (needed by open3d)"; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null; \
	fi
	@# report's HTML page is checked (and screenshotted for the demo) by a headless Chromium.
	@if ! command -v chromium >/dev/null 2>&1; then \
	  echo "installing chromium (headless check of the report's HTML page)"; \
	  if [ "$$(id -u)" = 0 ]; then SUDO=""; else SUDO="sudo"; fi; \
	  $$SUDO apt-get update -qq && DEBIAN_FRONTEND=noninteractive $$SUDO apt-get install -y -qq chromium >/dev/null; \
	fi

$(STAMP): pyproject.toml | sysdeps
	$(PY) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip setuptools wheel
	$(BIN)/pip install -q -e '.[test]'
	@touch $(STAMP)

demo: $(STAMP) sysdeps
	MPLBACKEND=Agg $(BIN)/python examples/demo.py --out $(DEMO_OUT)

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/mypy

# The suite on every core (pytest-xdist); tests/conftest.py groups the tests that share data built
# once onto one worker and starts the longest groups first. `make test PYTEST_N=0` runs it serially;
# PYTEST_ARGS adds options (`make test PYTEST_ARGS=--durations=20`). mypy (35 CPU seconds without
# its cache, as on a fresh clone) runs beside pytest, its report printed after pytest's; either
# failing fails the target.
PYTEST_N ?= auto
PYTEST_ARGS ?=
test: $(STAMP) sysdeps
	$(BIN)/ruff check .
	@$(BIN)/mypy > $(VENV)/mypy.log 2>&1 & mypy_pid=$$!; \
	echo "$(BIN)/mypy (beside pytest; its report below)"; \
	echo "MPLBACKEND=Agg $(BIN)/python -m pytest -n $(PYTEST_N) --dist loadfile --no-loadscope-reorder $(PYTEST_ARGS)"; \
	MPLBACKEND=Agg $(BIN)/python -m pytest -n $(PYTEST_N) --dist loadfile --no-loadscope-reorder $(PYTEST_ARGS); \
	rc=$$?; wait $$mypy_pid; mrc=$$?; echo "$(BIN)/mypy:"; cat $(VENV)/mypy.log; \
	[ $$rc -eq 0 ] && [ $$mrc -eq 0 ]

bench: $(STAMP) sysdeps
	MPLBACKEND=Agg $(BIN)/python benchmarks/run_all.py

clean:
	rm -rf $(VENV) $(DEMO_OUT) .pytest_cache .mypy_cache .ruff_cache build *.egg-info
