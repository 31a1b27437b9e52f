# Every target works on a fresh clone: the venv is created and the package installed on demand,
# at the tested versions in requirements/constraints.txt (refreshed by `make constraints`).
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
CONSTRAINTS := requirements/constraints.txt
BENCH_RUNS ?= 3

.PHONY: test test-slow demo bench studies lint docs constraints fuzz clean distclean

$(STAMP): pyproject.toml $(CONSTRAINTS)
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) setuptools
	$(BIN)/python -m pip install --quiet -c $(CONSTRAINTS) -e '.[dev,cluster,docs,pardiso]'
	touch $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check fruitcli tests docs
	$(BIN)/ruff format --check fruitcli tests docs
	$(BIN)/mypy  # the package and the benchmarks, as [tool.mypy] in pyproject.toml says

# The tests but the slow end-to-end cases (pytest's mark `slow`); `make test-slow` runs
# those, and CI runs both.
test: $(STAMP) lint
	MPLBACKEND=Agg $(BIN)/python -m pytest -m "not slow"

test-slow: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python -m pytest -m slow

demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/fruit demo --out out

# The HTML site in build/docs/ (reference pages generated from the code; warnings are errors,
# internal links checked).
docs: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python docs/generate.py
	$(BIN)/python -m sphinx -b html -W --keep-going -n -q docs build/docs

studies: $(STAMP)
	MPLBACKEND=Agg $(BIN)/fruit study stability --out out/study-stability
	MPLBACKEND=Agg $(BIN)/fruit study runtime pipelines/fruit-deformed.toml --out out/study-runtime
	MPLBACKEND=Agg $(BIN)/fruit study runtime pipelines/fruit-breathing.toml --out out/study-runtime-breathing
	MPLBACKEND=Agg $(BIN)/fruit study bench pipelines/fruit-rest.toml --out out/study-bench

# Every benchmark, BENCH_RUNS times (a script that sets MAX_RUNS = n, at most n times); the
# figures (min/median/max over the runs) go to build/bench/bench.json, from which `make docs`
# makes the performance page.
bench: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python tests/performance/run_all.py --runs $(BENCH_RUNS) --json build/bench/bench.json

# Every reader and parser fuzzed for FUZZ_SECONDS in all: cases tried and failures per target,
# written to the documentation's reliability page.
FUZZ_SECONDS ?= 600
fuzz: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python tests/robustness/fuzz_run.py --seconds $(FUZZ_SECONDS) \
		--markdown docs/reliability.md

# Rewrite the tested versions from the venv as it is now (after installing what you tested).
constraints: $(STAMP)
	( echo "# Tested versions, written by 'make constraints' from the venv; 'make' installs these."; \
	  $(BIN)/python -m pip freeze --all --exclude-editable | grep -v -E '^(pip)==' ) > $(CONSTRAINTS)

clean:
	rm -rf out .pytest_cache build *.egg-info fruitcli.egg-info docs/_generated
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
