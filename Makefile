# Two set-up commands for a fresh machine: `make demo` (main job) and `make test` (tests).
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test test-slow bench clean system-deps

# System packages for headless rendering and browser tests (Mesa EGL, Chromium); a no-op where
# they are present or where the script is absent.
system-deps:
	@if [ -x .ci/system-deps ]; then .ci/system-deps; fi

$(BIN)/robot-rise: pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[test]'
	touch $@

demo: $(BIN)/robot-rise system-deps
	$(BIN)/robot-rise demo --out out/demo

test: $(BIN)/robot-rise system-deps
	$(BIN)/python -m pytest -q

test-slow: $(BIN)/robot-rise
	$(BIN)/python -m pytest -q -m slow

bench: $(BIN)/robot-rise
	$(BIN)/robot-rise bench validity

clean:
	rm -rf $(VENV) out
