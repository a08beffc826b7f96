# Two set-up commands for a fresh machine: `make demo` (main job) and `make test` (tests).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test test-slow bench bench-planning clean system-deps

# System packages for headless rendering and browser tests (Mesa EGL, Chromium); a no-op where
# they are present or where the script is absent.
system-deps:
	@if [ -x .ci/system-deps ]; then .ci/system-deps; fi

$(BIN)/robot-rise: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip 'setuptools>=77'
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

demo: $(BIN)/robot-rise system-deps
	$(BIN)/robot-rise demo --out out/demo

test: $(BIN)/robot-rise system-deps
	$(BIN)/python -m pytest -q

test-slow: $(BIN)/robot-rise
	$(BIN)/python -m pytest -q -m slow

# The figures in BENCHMARKS.md (long: the rise benchmark takes ~10 minutes on 2 cores).
bench: $(BIN)/robot-rise
	$(BIN)/robot-rise bench validity
	$(BIN)/robot-rise bench bus
	$(BIN)/robot-rise library bench
	$(BIN)/robot-rise bench rise --n-per-kind 20 --seed 0

bench-planning: $(BIN)/robot-rise
	$(BIN)/pip install --quiet -e '.[bench]'
	$(BIN)/robot-rise bench planning --seed 1 --budget 10 --out out/bench_planning.json

clean:
	rm -rf $(VENV) out
