# Two commands for a fresh machine with Python 3.11: `make demo` and `make test`.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.uvisi-installed

.PHONY: test demo bench killcheck install clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench]'
	@touch $(STAMP)

install: $(STAMP)

test: $(STAMP)
	$(BIN)/python -m pytest -q

demo: $(STAMP)
	$(BIN)/uvisi demo

bench: $(STAMP)
	$(BIN)/python -m bench.report

# kill uvisi event at random moments; every recording left must open, verify and replay (~2 min)
killcheck: $(STAMP)
	$(BIN)/python -m tests.kill_anywhere 20

clean:
	rm -rf $(VENV) build *.egg-info
