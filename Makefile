# The two commands: `make demo` and `make test`. Both create .venv on first use.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test install clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/pip install --quiet -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(BIN)/bulletnav demo

test: $(STAMP)
	$(BIN)/ruff check bulletnav tests
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) runs/demo .pytest_cache
