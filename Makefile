# Quick start: `make study` (the paper's study on built-in simulated data) and `make test`.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: study test lint bench samples dist docs clean-venv

$(STAMP): pyproject.toml
	$(PYTHON) -c 'import sys; assert sys.version_info >= (3, 11), "roughsense needs Python >= 3.11"'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

study: $(STAMP)
	$(BIN)/roughsense study --out report --force

# One worker per core, at most 4 (pytest-xdist); a test file's tests share a worker, so its module fixtures run once.
# Files are handed out in collection order, which tests/conftest.py starts with the longest (LONGEST_FILES).
# Bytecode is cached even where the shell sets PYTHONDONTWRITEBYTECODE: the suite starts hundreds of interpreters,
# and compiling the package (and rewriting the tests' asserts) afresh in each cost a fifth of its time (BENCHMARKS.md).
test: $(STAMP)
	PYTHONDONTWRITEBYTECODE= $(BIN)/python -m pytest -q --numprocesses auto --maxprocesses 4 --dist loadfile --no-loadscope-reorder

# ruff (pyproject's [tool.ruff]) and the import layers (pyproject's [tool.importlinter]; docs/architecture.md).
lint: $(STAMP)
	$(BIN)/ruff check src tests benchmarks scripts
	$(BIN)/lint-imports --no-cache

bench: $(STAMP)
	for script in benchmarks/bench_*.py; do $(BIN)/python $$script || exit 1; done

# Quiet when it works (the line naming the wheel and sdist); the whole build log when it does not.
dist: $(STAMP)
	@log=$$(mktemp) && if $(BIN)/python -m build --outdir dist . >$$log 2>&1; then tail -n 1 $$log; rm -f $$log; \
	else cat $$log; rm -f $$log; exit 1; fi

# The API reference from the public names' docstrings (pdoc), into build/api; any warning fails (tests/test_api_docs.py
# runs the same command).
docs: $(STAMP)
	@rm -rf build/api && err=$$($(BIN)/python -m pdoc --docformat numpy --output-directory build/api roughsense \
	2>&1 >/dev/null) && [ -z "$$err" ] || { echo "$$err"; exit 1; }; echo "build/api/roughsense.html"

samples: $(STAMP)
	$(BIN)/python scripts/make_samples.py

clean-venv:
	rm -rf $(VENV)
