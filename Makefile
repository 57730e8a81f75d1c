# Two commands for a fresh machine with Python 3.11: `make demo` and `make test`.
PYTHON ?= $(shell command -v python3.11 2>/dev/null || command -v python3)
VENV   := .venv
BIN    := $(VENV)/bin
# setuptools prints an information box on every editable install ("be careful with folders named
# like your package": the package is uvisi, no folder is): nothing a user can act on, so not shown
PIP    := PYTHONWARNINGS="ignore:Editable installation" $(BIN)/python -m pip
# the demo needs the package alone; the tests and benchmarks need their extras as well
STAMP_RUN := $(VENV)/.uvisi-installed-run
STAMP     := $(VENV)/.uvisi-installed

.PHONY: test demo bench install clean fuzz coverage killcheck docs-check interchange

$(STAMP_RUN): pyproject.toml
	@echo "make: setting up $(VENV) (first run only): installing uvisi and its dependencies..."
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(PIP) install --progress-bar on --no-input -e .
	@$(BIN)/python -c "import hil_harness.event.io" || (echo "make: the install failed" >&2; exit 1)
	@touch $(STAMP_RUN)

$(STAMP): $(STAMP_RUN)
	@echo "make: installing the test, benchmark and viewer-test extras (first run only)..."
	$(PIP) install --progress-bar on --no-input -e '.[test,bench,view]'
	@touch $(STAMP)

install: $(STAMP)

# the suite in two worker processes (pytest-xdist): on a cold cache each compiles what its tests
# reach, numba's compile lock has the other wait and load a kernel one of them is compiling, and the
# warm tests share the cores (make test TEST_WORKERS=4 on a larger machine; 0: one process)
TEST_WORKERS ?= 2
test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS)

# the decoders and TOML loaders fuzzed at full size: 10,000 streams / texts per decoder and loader,
# 1,000 hypothesis examples per property (make test runs 300 and 40-150)
fuzz: $(STAMP)
	UVISI_FUZZ_CASES=10000 $(BIN)/python -m pytest -q -p no:cacheprovider \
		tests/flight/test_messages.py tests/harness/test_fuzz_loaders.py

# branch coverage of the Python-visible code (njit bodies excluded: pyproject [tool.coverage])
coverage: $(STAMP)
	$(BIN)/python -m pytest -q -p no:cacheprovider -n $(TEST_WORKERS) --cov --cov-report=
	@for p in flightsw hil_harness; do \
		printf '%s branch coverage: ' $$p; \
		$(BIN)/python -m coverage report --include="$$p/*" --format=total; done

# every command and Python example of README.md and docs/*.md, run and its output checked (~25 min,
# CI runs it; make test runs the fast documents: api, budget, cli, design, fidelity, formats);
# one document: make docs-check DOCS=README.md (the README's command blocks: ~2 min)
docs-check: $(STAMP)
	$(BIN)/python docs/check_commands.py $(DOCS)

demo: $(STAMP_RUN)
	$(BIN)/uvisi demo

bench: $(STAMP)
	$(BIN)/python -m bench.report

# kill uvisi event at random moments; every recording left must open, verify and replay (~2 min)
killcheck: $(STAMP)
	$(BIN)/python -m tests.kill_anywhere 20

# recordings read by other HDF5 builds: Debian's h5dump (hdf5-tools) and h5py<3.12 on HDF5 1.14,
# installed from PyPI into .venv-h5py-old on first use (make test skips the h5py part without it)
interchange: $(STAMP)
	UVISI_OLD_H5PY=1 $(BIN)/python -m pytest -q -p no:cacheprovider tests/harness/test_recording_interchange.py

clean:
	rm -rf $(VENV) .venv-h5py-old .numba_cache build *.egg-info
