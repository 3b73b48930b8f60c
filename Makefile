# Tank-test pipeline.  The two commands a newcomer needs:
#   make pipeline   build .venv if missing, run every stage on the default data, render reports
#   make test       build .venv if missing, run the test suite
# Python (pipeline/build.py) decides what is out of date, so make reruns only what changed.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SHARED ?= ../shared
PROC   := data/processed

# Datasets: the built-in virtual tank always; the measured HSVA KVLCC2 zigzags when ../shared is there;
# any folder a user makes in data/raw/<name>/, and files dropped straight into data/raw/ (dataset
# "local").  Their names are found by Python (`$(PY) -m pipeline run --list`) and never become words
# of a shell recipe: a folder called `x$$(touch X)` or `my runs` is just a name.
#
# Staleness is decided in Python too (pipeline/build.py): each stage of each dataset reruns when the
# content of its inputs changes or the source of any pipeline module it imports (config.py, model.py,
# io.py, cli/, its stage package, ...), and reruns everything downstream of it.  Reports re-render
# only pages whose inputs, notebook or report code changed.

.PHONY: pipeline test bench reports venv clean dataset datasets help lint

help:
	@echo "make pipeline | make test | make test-long | make bench | make reports | make clean"
	@echo "make dataset D=NAME (one dataset) | make datasets (list the names) | make lab [D=NAME] (notebooks)"

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name tanktest --display-name "tanktest (.venv)" > /dev/null
	@touch $@

venv: $(STAMP)

# A dataset or stage that fails stops only what reads its outputs: the other datasets and stages are
# built and every report whose inputs exist is rendered; then the exit status is non-zero.
pipeline: $(STAMP)
	@start=$$(date +%s); \
	$(PY) -m pipeline run --all --shared '$(SHARED)'; st=$$?; \
	$(PY) -m pipeline report --all --changed --keep-going --out reports || st=$$((st ? st : 2)); \
	echo "pipeline finished in $$(( $$(date +%s) - start )) s; reports in reports/index.html"; \
	if [ $$st -ne 0 ]; then echo "pipeline: not everything was built or rendered (see the errors above)" >&2; fi; \
	exit $$st

datasets: $(STAMP)
	@$(PY) -m pipeline run --list --shared '$(SHARED)'

# One dataset: make dataset D=NAME.  D reaches the shell only as the quoted environment variable "$$D",
# which the shell never re-parses (no expansion of $$(...), backquotes or spaces inside it), joined to
# its option (--dataset=NAME) so that a name starting with "-" is never read as an option.
D ?= virtual
export D
dataset: $(STAMP)
	$(PY) -m pipeline run --dataset="$$D" --shared '$(SHARED)'

# ---------------------------------------------------------------- reports, tests, benchmarks
reports: $(STAMP)
	$(PY) -m pipeline report --all --changed --out reports

# make test       every area, CI-sized (under 10 minutes on 2 cores: 7 min 56 s measured on 2 idle
#                 cores, docs/operations.md, "Tests"); the tests marked
#                 `long` are left out (pyproject.toml's addopts): whole-pipeline builds and rebuilds, every
#                 report rendered, process kills, long selections
# make test-long  only those long tests (tens of minutes on 2 cores)
# make test-all   both
# --dist loadgroup: tests that share an expensive module fixture carry one xdist_group mark, so it is
# built once, on one worker.  --no-loadscope-reorder: the tests are handed out in tests/conftest.py's
# order, the known slow ones (tests/known_slow.txt) longest first, so that both workers finish together
PYTEST := $(PY) -m pytest -n 2 --dist loadgroup --no-loadscope-reorder
.PHONY: test-long test-all
test: $(STAMP)
	$(PYTEST) --durations=15

test-long: $(STAMP)
	$(PYTEST) -m long --durations=15

test-all: $(STAMP)
	$(PYTEST) -m "" --durations=15

# make lab: JupyterLab on this project, notebooks/*.py opening as notebooks (docs/reports.md);
#           make lab D=hsva opens them on that dataset (its stages run first: make dataset D=hsva).
#           Listens on 127.0.0.1 only, with Jupyter's token.
.PHONY: lab
lab: $(STAMP)
	$(PY) -m pipeline.report.lab --dataset "$$D"

bench: $(STAMP)
	$(PY) -m pipeline bench

lint: $(STAMP)
	$(VENV)/bin/ruff check .

# Removes what the pipeline made, never a committed file: the virtual tank's runs go, its
# dataset.toml (committed) stays; tests/test_build.py checks every tracked file survives.
clean:
	rm -rf $(PROC)/* reports/*.html reports/*/
	@if [ -d data/raw/virtual ]; then \
	  find data/raw/virtual -mindepth 1 -maxdepth 1 ! -name dataset.toml -exec rm -rf {} + ; fi
	@touch $(PROC)/.gitkeep reports/.gitkeep

# ---------------------------------------------------------------- studies on Dask
# make study                      the full detection-power study (resumable: rerun to continue)
# make study SPEC=studies/autopilot.toml STUDY_ARGS="--scheduler tcp://host:8786"
SPEC ?= studies/power-full.toml
.PHONY: study
study: $(STAMP)
	$(PY) -m pipeline study $(SPEC) --out data/studies/$(basename $(notdir $(SPEC))) $(STUDY_ARGS)

# make fuzz: the property tests with fresh random examples, ten times as many (make test replays
#            the same derandomised ones every run; see tests/conftest.py)
.PHONY: fuzz
fuzz: $(STAMP)
	TANKTEST_HYPOTHESIS=fuzz $(PY) -m pytest -n 2 tests/test_fuzzy.py tests/test_ingest_bad.py

# make generalise                 all 32 truth cases + a fresh draw + KVLCC2 + the Mariner at 7 noise seeds,
#                                 with and without a process disturbance, + the tanker at 4 seeds,
#                                 + the container ship, + the cross-flow ferry and bulker (model-scale CSV)
#                                 (tests/test_diagnose_generalise.py)
#                                 (make test runs a CI-sized cut of 8 cases)
.PHONY: generalise
generalise: $(STAMP)
	TANKTEST_GENERALISE=full $(PY) -m pytest -n 2 -m generalise tests/test_diagnose_generalise.py
