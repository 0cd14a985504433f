# gridmap: the targets a newcomer guesses. Everything runs inside .venv, created on demand.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
DEMO_OUT := out/demo
# the compiled mapping kernels: pip builds them, so a change to them reinstalls
KERNELS := setup.py gridmap_cli/mapping/models/_ckernels.c gridmap_cli/readers/ros/_cwalk.c \
	gridmap_cli/poses/correction/_cbranch.c gridmap_cli/poses/correction/_csheet.c

.PHONY: install dev demo test lint format bench samples goldens doc-outputs experiment stress quality corpus overview-image clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip

# runtime install; redone when pyproject.toml or the C kernels change (pip builds them)
$(VENV)/.installed: pyproject.toml $(KERNELS) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

# runtime + development tools (pytest, hypothesis, ruff, mypy)
$(VENV)/.installed-dev: pyproject.toml $(KERNELS) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $@ $(VENV)/.installed

install: $(VENV)/.installed

dev: $(VENV)/.installed-dev

demo: install
	@mkdir -p $(DEMO_OUT)
	$(BIN)/gridmap build samples/corridor_loop.mcap -o $(DEMO_OUT)/corridor_loop.png --force
	@echo "demo map written to $(DEMO_OUT)/corridor_loop.png and $(DEMO_OUT)/corridor_loop.yaml"

test: dev
	$(BIN)/python -m pytest

lint: dev
	$(BIN)/ruff check gridmap_cli tests bench samples
	$(BIN)/ruff format --check gridmap_cli tests bench samples
	$(BIN)/mypy

format: dev
	$(BIN)/ruff format gridmap_cli tests bench samples
	$(BIN)/ruff check --fix gridmap_cli tests bench samples

bench: install
	$(BIN)/python bench/bench_build.py

# regenerate the bundled worlds, paths and simulated logs in samples/ (then `make goldens` if
# the corridor_loop run changed on purpose)
samples: install
	$(BIN)/python samples/make_samples.py

# simulate, build every mapping mode, evaluate against ground truth; then the CARMEN logs
# (bench/carmen_experiment.py), scan matching on them (bench/scan_match.py, one core), the SLAM
# benchmark on the corrected logs (bench/slam_relations.py), and last every shared real log
# (bench/real_logs.py, two logs at a time: odometry, scan-matched and slam on the benchmark's raw
# bags, scored on their relations, and on the six corrected CARMEN logs, APE against their
# corrected poses), that table printed at the end; writes docs/experiments.md,
# docs/scan-matching-results.md and their images (needs matplotlib, in the dev extra). Nothing
# is cached: every track is computed again. About 6 minutes on 2 quiet cores: the real logs take
# about 290 CPU seconds, the raw Intel bag about 90 of them (17 minutes of wall clock on a machine
# loaded six times over); without ../shared/data only the simulated part runs. To check one
# change on a few logs: .venv/bin/python bench/real_logs.py --logs aces,intel --pose slam --no-doc
experiment: dev
	$(BIN)/python bench/experiment.py

# the pose graph on logs made unlike the ones it was developed on, as stand-ins for held-out
# logs: the raw benchmark bags at every 2nd/3rd/4th scan, from a third or two thirds on, with
# every 2nd beam (bench/slam_stress.py, rewrites the table in docs/slam-stress.md), then the
# same bags with their odometry left out (bench/no_odometry.py, prints its table); about 40
# minutes on 2 cores; needs ../shared/data
stress: dev
	$(BIN)/python bench/slam_stress.py --jobs 2
	$(BIN)/python bench/no_odometry.py

# the quality score without ground truth against the NLL with it, on the six shared CARMEN logs
# (bench/quality_ranking.py); rewrites the table in docs/quality.md; 15 minutes on 2 cores
quality: dev
	$(BIN)/python bench/quality_ranking.py

# regenerate samples/golden/ (the conformance test's expected dump and map checksums, and the
# trinary map) from samples/corridor_loop.csv; only when a change to them is intended
goldens: install
	$(BIN)/python -m tests.golden

# rewrite the docs' output blocks (fenced ``text output: gridmap ...``) with what their commands
# print now; only when a change of output is intended (tests/test_readme.py compares them)
doc-outputs: install
	$(BIN)/python -m tests.doc_outputs

# write the malformed-input corpus the tests run (tests/corpus/generate.py) to out/corpus, to
# look at the broken files and cases.json
corpus: dev
	$(BIN)/python -m tests.corpus.generate out/corpus

# docs/images/batch-overview.png: a screenshot of a real batch overview page (needs chromium)
overview-image: install
	$(BIN)/python bench/overview_image.py

clean:
	rm -rf $(VENV) out build *.egg-info .pytest_cache .ruff_cache .mypy_cache bench/.cache
