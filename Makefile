# Tank-test pipeline.  The two commands a newcomer needs:
#   make pipeline   build .venv if missing, run every stage on the default data, render reports
#   make test       build .venv if missing, run the test suite
# Stages are file targets, so make reruns only what is out of date.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
SHARED ?= ../shared
HSVA   := $(SHARED)/data/kvlcc2_hsva
PROC   := data/processed

# Datasets: the built-in virtual tank always; the measured HSVA KVLCC2 zigzags when ../shared is there;
# any folder a user makes in data/raw/<name>/, and files dropped straight into data/raw/ (dataset
# "local"), raw files of any supported format.
USER_DATASETS := $(filter-out virtual,$(notdir $(patsubst %/,%,$(wildcard data/raw/*/))))
LOCAL_FILES   := $(filter-out %.md %.gitkeep,$(wildcard data/raw/*.*))
DATASETS ?= virtual $(if $(wildcard $(HSVA)/*.dat),hsva) $(USER_DATASETS) $(if $(LOCAL_FILES),local)

.PHONY: pipeline test bench reports venv clean dataset help lint

help:
	@echo "make pipeline | make test | make bench | make reports | make clean"

$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	$(PY) -m ipykernel install --sys-prefix --name tanktest --display-name "tanktest (.venv)" > /dev/null
	@touch $@

venv: $(STAMP)

pipeline: $(STAMP)
	@start=$$(date +%s); \
	for d in $(DATASETS); do $(MAKE) --no-print-directory dataset D=$$d || exit 1; done; \
	$(MAKE) --no-print-directory reports && \
	echo "pipeline finished in $$(( $$(date +%s) - start )) s; reports in reports/index.html"

# ---------------------------------------------------------------- one dataset, stage by stage
D ?= virtual
P := $(PROC)/$(D)
RAW_virtual := data/raw/virtual
RAW_hsva    := $(HSVA)
RAW_local   := data/raw
RAW := $(or $(RAW_$(D)),data/raw/$(D))
RAW_FILES = $(shell find $(RAW)/ -maxdepth 1 -type f ! -name '.*' ! -name '*.md' ! -name '*.stamp' | sort)

dataset: $(P)/.done

data/raw/virtual/.stamp: $(STAMP) $(wildcard pipeline/tank/*.py) pipeline/config.py
	$(PY) -m pipeline tank --out data/raw/virtual
	@touch $@

RAW_DEPS = $(if $(filter virtual,$(D)),data/raw/virtual/.stamp,$(RAW_FILES))

$(P)/runs/index.json: $(RAW_DEPS) $(wildcard pipeline/ingest/*.py)
	$(PY) -m pipeline ingest $(RAW_FILES) --out $(P)/runs --dataset $(D)

$(P)/identify/.done: $(P)/runs/index.json $(wildcard pipeline/identify/*.py)
	$(PY) -m pipeline identify --dataset $(D) --algorithm srukf-ffm
	$(PY) -m pipeline identify --dataset $(D) --algorithm ffm-ukf
	@touch $@

$(P)/validate/metrics.json: $(P)/identify/.done $(wildcard pipeline/validate*.py pipeline/validate/*.py)
	$(PY) -m pipeline validate --dataset $(D)

$(P)/indices/indices.json: $(P)/identify/.done $(wildcard pipeline/indices/*.py)
	$(PY) -m pipeline indices --dataset $(D)

$(P)/control/metrics.json: $(P)/indices/indices.json $(wildcard pipeline/control/*.py)
	$(PY) -m pipeline control --dataset $(D)

$(P)/diagnose/diagnosis.json: $(P)/runs/index.json $(wildcard pipeline/diagnose/*.py)
	$(PY) -m pipeline diagnose --dataset $(D)

$(P)/.done: $(P)/validate/metrics.json $(P)/indices/indices.json $(P)/control/metrics.json $(P)/diagnose/diagnosis.json
	@touch $@

# ---------------------------------------------------------------- reports, tests, benchmarks
reports: $(STAMP)
	$(PY) -m pipeline report --datasets $(DATASETS) --out reports

test: $(STAMP)
	$(PY) -m pytest -n 2 --durations=15

bench: $(STAMP)
	$(PY) -m pipeline bench

lint: $(STAMP)
	$(VENV)/bin/ruff check .

clean:
	rm -rf $(PROC)/* reports/*.html reports/*/ data/raw/virtual
	@touch $(PROC)/.gitkeep reports/.gitkeep

# ---------------------------------------------------------------- studies on Dask (issue 12)
# make study                      the full detection-power study (resumable: rerun to continue)
# make study SPEC=studies/autopilot.toml STUDY_ARGS="--scheduler tcp://host:8786"
SPEC ?= studies/power-full.toml
.PHONY: study
study: $(STAMP)
	$(PY) -m pipeline study $(SPEC) --out data/studies/$(basename $(notdir $(SPEC))) $(STUDY_ARGS)
