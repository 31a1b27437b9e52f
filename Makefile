# Every target works on a fresh clone: the venv is created and the package installed on demand.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: test demo bench studies lint clean fuzz

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev,cluster]'
	touch $(STAMP)

lint: $(STAMP)
	$(BIN)/ruff check fruitcli tests

test: $(STAMP) lint
	MPLBACKEND=Agg $(BIN)/python -m pytest

demo: $(STAMP)
	MPLBACKEND=Agg $(BIN)/fruit demo --out out

studies: $(STAMP)
	MPLBACKEND=Agg $(BIN)/fruit study stability --out out/study-stability
	MPLBACKEND=Agg $(BIN)/fruit study runtime pipelines/fruit-deformed.toml --out out/study-runtime
	MPLBACKEND=Agg $(BIN)/fruit study runtime pipelines/fruit-breathing.toml --out out/study-runtime-breathing
	MPLBACKEND=Agg $(BIN)/fruit study bench pipelines/fruit-rest.toml --out out/study-bench

# every reader and parser fuzzed for FUZZ_SECONDS in all: cases tried and failures per target
FUZZ_SECONDS ?= 600
fuzz: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python tests/fuzz_run.py --seconds $(FUZZ_SECONDS) \
		--markdown docs/reliability.md

bench: $(STAMP)
	MPLBACKEND=Agg $(BIN)/python tests/bench/run_all.py

clean:
	rm -rf out .pytest_cache build *.egg-info fruitcli.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
