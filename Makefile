# fiveaxis: `make run` and `make test` set everything up themselves (a .venv in this folder).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
MACHINE ?= li2018

.PHONY: install run test derive bench lint clean

$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@echo "installing fiveaxis and its dependencies into $(VENV) (log: $(VENV)/install.log)"
	@$(BIN)/python -m pip install --quiet --upgrade pip > $(VENV)/install.log 2>&1 || { cat $(VENV)/install.log; exit 1; }
	@$(BIN)/python -m pip install --quiet -e ".[test]" >> $(VENV)/install.log 2>&1 || { cat $(VENV)/install.log; exit 1; }
	@touch $(STAMP)

install: $(STAMP)

## the main job on the paper's machine and on the bundled example measurements
run: install
	$(BIN)/fiveaxis table2 --machine li2018 --convention printed --reconcile
	@scripts/run-main.sh $(BIN)

test: install
	$(BIN)/python -m pytest -q
	$(BIN)/lint-imports

## regenerate the kernels in generated/ from machines/ and print Table 2 (time is printed per machine)
derive: install
	$(BIN)/fiveaxis derive
	$(BIN)/fiveaxis table2 --machine $(MACHINE) --latex

bench: install
	$(BIN)/python -m pip install --quiet -e ".[bench]" || echo "bench: optional baselines did not install"
	$(BIN)/python bench/run.py
	$(BIN)/python bench/bench_diagnose.py
	$(BIN)/python bench/bench_plan.py

lint: install
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) .pytest_cache generated/__pycache__
