# fiveaxis: `make run` and `make test` set everything up themselves (a .venv in this folder).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed-stamp
MACHINE ?= li2018

.PHONY: install system-deps warm run test test-fast test-scale test-linuxcnc fuzz derive bench bench-scale lint clean

## uv installs the same packages as pip (the same versions from the same index) in 8 s against pip's 59 s on a
## fresh clone; pip does it where uv cannot be had
$(STAMP): pyproject.toml
	@test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	@echo "installing fiveaxis and its dependencies into $(VENV) (log: $(VENV)/install.log)"
	@{ $(BIN)/python -m pip install --quiet uv && \
	   $(BIN)/uv pip install --quiet --python $(BIN)/python -e ".[test]"; } > $(VENV)/install.log 2>&1 || \
	 { echo "uv unavailable (see $(VENV)/install.log): installing with pip"; \
	   $(BIN)/python -m pip install --quiet --upgrade pip >> $(VENV)/install.log 2>&1 && \
	   $(BIN)/python -m pip install --quiet -e ".[test]" >> $(VENV)/install.log 2>&1; } || \
	 { cat $(VENV)/install.log; exit 1; }
	@touch $(STAMP)

install: $(STAMP)

## Debian packages some tests need: headless Chromium (the report's browser test and PDF) and LinuxCNC (its G-code
## interpreter rs274 for toolpaths and plans; the controller for `make test-linuxcnc`). Installed with apt-get when
## missing (as root); harmless when present; where apt-get is unavailable those tests skip with the reason.
SYSTEM_PACKAGES := chromium chromium-driver linuxcnc-uspace
system-deps:
	@if command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1 && [ -x /usr/bin/rs274 ]; then :; \
	elif command -v apt-get >/dev/null 2>&1 && [ "$$(id -u)" -eq 0 ]; then \
	  echo "installing the Debian packages $(SYSTEM_PACKAGES) (apt-get)"; \
	  { DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PACKAGES) || \
	    { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq $(SYSTEM_PACKAGES); }; } \
	    >/dev/null 2>&1 || echo "system-deps: apt-get could not install $(SYSTEM_PACKAGES) (those tests will skip)"; \
	else echo "system-deps: $(SYSTEM_PACKAGES) missing and apt-get unavailable as this user (those tests will skip)"; fi

## the main job on the paper's machine and on the bundled example measurements; writes the reports in out/
run: install system-deps
	$(BIN)/fiveaxis table2 --machine li2018 --convention printed --reconcile
	@scripts/run-main.sh $(BIN)

## the kernels of every shipped machine compiled into numba's cache once, in one process, before the tests run on
## both cores (pytest-xdist; a file's tests stay on one worker; one BLAS thread per worker: two workers with two
## threads each on two cores ran the suite 4% slower, 529 -> 506 s)
PYTEST := OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 --dist loadfile

warm: install
	@$(BIN)/python scripts/warm-kernels.py

## everything but the scale tests (the slow ones too: the browser, full grids, null-set series)
test: install
	@$(MAKE) --no-print-directory -j2 system-deps warm     # the Debian packages download while the kernels compile
	$(PYTEST) -m "not scale" --durations=15
	$(BIN)/lint-imports

## the scale tests: 400,000 poses in row blocks, Dask clusters, the installed wheel, diagnoses in row blocks against
## the same in memory, bench_scale's smoke run (CI runs them after make test)
test-scale: install warm
	$(PYTEST) -m scale

## the loop of a developer: everything but the tests marked slow (one case of each parametrized family stays):
## 150 s of pytest with a warm cache on 2 cores, against about 290 s for `make test`'s
test-fast: install warm
	$(PYTEST) -m "not slow and not scale"
	$(BIN)/lint-imports

## against the real LinuxCNC 2.9 (Debian linuxcnc-uspace, installed when missing; skipped with a one-line
## message where the package manager is not available)
test-linuxcnc: install
	@scripts/linuxcnc-deps.sh; rc=$$?; if [ $$rc -eq 77 ]; then exit 0; elif [ $$rc -ne 0 ]; then exit $$rc; fi; \
	$(BIN)/python -m pytest -q --linuxcnc tests/test_linuxcnc.py tests/test_linuxcnc_kins.py tests/test_linuxcnc_thermal.py

## the adversarial corpus (tests/adversarial.py): every command under hostile files, absurd numbers, symbolic
## links and kill -9, each trial a subprocess under a memory limit and a timeout; prints the totals per class
## (the suite runs a fast subset). FUZZ_ARGS: e.g. --only gsa, --jobs 1, --pythonpath OTHER_TREE.
fuzz: install system-deps
	nice $(BIN)/python tests/adversarial.py $(FUZZ_ARGS)

## regenerate the kernels in generated/ from machines/ and print Table 2 (time is printed per machine)
derive: install
	$(BIN)/fiveaxis derive
	$(BIN)/fiveaxis table2 --machine $(MACHINE) --latex

## the benchmarks (bench/): each prints its ratios measured in one run; tests/test_bench.py runs every script on
## tiny sizes so that none rots. bench-scale: fit and diagnose of 10^4..10^6 poses, each in its own process
bench: install
	@$(BIN)/uv pip install --quiet --python $(BIN)/python -e ".[bench]" 2>/dev/null || \
	  $(BIN)/python -m pip install --quiet -e ".[bench]" || echo "bench: optional baselines did not install"
	$(BIN)/python bench/run.py
	$(BIN)/python bench/baseline_split.py
	$(BIN)/python bench/bench_diagnose.py
	$(BIN)/python bench/bench_profiles.py
	$(BIN)/python bench/bench_plan.py

bench-scale: install warm
	$(BIN)/python bench/bench_scale.py

lint: install
	$(BIN)/lint-imports

clean:
	rm -rf $(VENV) .pytest_cache generated/__pycache__
