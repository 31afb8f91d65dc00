# Two commands for a new user: `make demo` (the main job) and `make test`.
# Each bootstraps .venv on first use.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp

.PHONY: demo test test-extras lint bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install -q --upgrade pip
	$(BIN)/python -m pip install -q -e ".[test,dev,calibrate]"
	touch $(STAMP)

# A 12-object table (seed 6) on which Alg. 1 starts with four grasps of two objects each.
demo: $(STAMP)
	$(BIN)/mog-drake pick --objects 12 --seed 6 --record out/pick.html

# On every core (pytest-xdist); `pytest tests/...` alone runs serially.
test: $(STAMP)
	$(BIN)/python -m pytest -q -n auto

# CI, after `make test`: sweeps on a real local Ray cluster, and the wheel installed outside
# the checkout (slower: they install Ray, and the package with its dependencies).
test-extras: $(STAMP)
	$(BIN)/python -m pip install -q -e ".[ray]"
	$(BIN)/python -m pytest -q -m extras

lint: $(STAMP)
	$(BIN)/ruff check mog_drake tests notebooks
	$(BIN)/ruff format --check mog_drake tests notebooks

bench: $(STAMP)
	$(BIN)/mog-drake bench geometry

clean:
	rm -rf $(VENV) out .pytest_cache
