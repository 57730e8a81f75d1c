# Two commands for a fresh machine with Python 3.11: `make demo` and `make test`.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
# the demo needs the package alone; the tests and benchmarks need their extras as well
STAMP_RUN := $(VENV)/.uvisi-installed-run
STAMP     := $(VENV)/.uvisi-installed

.PHONY: test demo bench install clean

$(STAMP_RUN): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e .
	@touch $(STAMP_RUN)

$(STAMP): $(STAMP_RUN)
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	@touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

demo: $(STAMP_RUN)
	$(BIN)/uvisi demo

bench: $(STAMP)
	$(BIN)/python -m bench.report

clean:
	rm -rf $(VENV) build *.egg-info
