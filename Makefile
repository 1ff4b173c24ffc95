# The two commands: `make demo` and `make test` (and `make check`, lint and the fast tests for day-to-day
# work; `make fuzz`, a longer fuzzing run). Each creates .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# pytest-xdist processes of `make test`, each running whole test modules (2: the CI machine's cores), in the
# order tests/conftest.py sets (longest first), not xdist's own (by a module's number of tests)
TEST_WORKERS ?= 2

.PHONY: demo test check fuzz install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/bulletnav demo

test: $(STAMP)
	$(BIN)/ruff check bulletnav tests
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir build/site
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# Day-to-day: ruff, the docs build and the tests not marked slow or gui (a few minutes on 2 cores);
# `make test`, which CI runs, stays the whole suite.
check: $(STAMP)
	$(BIN)/ruff check bulletnav tests
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict --quiet --site-dir build/site
	$(BIN)/python -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder -m "not slow and not gui"

# Property-based fuzzing of every parser, the env's kwargs and actions and the CLI with 20 times the
# examples of `make test`'s derandomized run, on random seeds; prints the examples per property.
fuzz: $(STAMP)
	HYPOTHESIS_PROFILE=fuzz $(BIN)/python -m pytest -q tests/test_fuzz.py tests/test_fuzz_models.py --hypothesis-show-statistics

clean:
	rm -rf $(VENV) runs/demo runs/demo-* .pytest_cache
