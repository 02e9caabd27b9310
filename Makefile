# The two commands of the README: `make run` and `make test`. Both set up on first use.
SHELL := /bin/bash
.DEFAULT_GOAL := help
IN_ENV := source env.sh &&
PY_SRC := src/bracing_engine/bracing_engine src/bracing_core/bracing_core src/bracing_ros/bracing_ros src/bracing_sim/bracing_sim src/bracing_controller/bracing_controller src/bracing_rcl/bracing_rcl src/bracing_analysis/bracing_analysis src/bracing_experiments/bracing_experiments src/bracing_recorder/bracing_recorder src/bracing_view/bracing_view src/bracing_mujoco/bracing_mujoco src/bracing_bringup/bracing_bringup

.PHONY: help setup test test-loaded test-slow lint typecheck docs docs-check pytest run bench lock clean

help:
	@echo "make run    - set up if needed, run the paper scenario braced, passive and in free space, print the table"
	@echo "make test   - set up if needed, then ruff, mypy and the pytest suite (the docs site built, warnings as errors)"
	@echo "make test-loaded - the pytest suite (or PYTEST_ARGS=\"test/test_x.py -k y\") beside one CPU-bound process per core"
	@echo "make test-slow - the long runs: 10 min of sim time; 3 pairs at once x 10 rounds; make run x 10 and in two clones at once"
	@echo "make bench  - benchmarks (engine vs MuJoCo, pair vs DDS bound, controller latency, scaling)"
	@echo "make docs   - the documentation site (Sphinx, MyST Markdown) into docs/_build/html (index.html)"
	@echo "make setup  - only the set-up (.venv, CMake fix, colcon build); idempotent"

setup:
	@bash tools/setup.sh

lint: setup
	@$(IN_ENV) ruff check src test bench tools

typecheck: setup
	@$(IN_ENV) mypy $(PY_SRC)

pytest: setup
	@$(IN_ENV) python -m pytest test $(PYTEST_ARGS)

# The site; its reference pages are generated (tools/docs_reference.py) and committed.
SPHINX := sphinx-build -b html -q docs docs/_build/html

docs: setup
	@$(IN_ENV) $(SPHINX)
	@echo "docs/_build/html/index.html"

# As `make test` builds it (test/test_docs.py): from scratch (-E), every warning an error (-W, all of
# them shown: --keep-going), every cross-reference checked (-n): a broken link or a stray page fails.
docs-check: setup
	@$(IN_ENV) $(SPHINX) -E -W --keep-going -n

test: lint typecheck pytest

# The suite on a machine as busy as a loaded CI runner: a CPU-bound burner per core (nproc) beside pytest,
# stopped whatever the result (tools/loaded.sh). PYTEST_ARGS, if given, replaces the whole suite.
test-loaded: setup
	@$(IN_ENV) bash tools/loaded.sh python -m pytest $(or $(PYTEST_ARGS),test)

# The long runs (10 minutes of sim time in lockstep: memory and constraint drift).
test-slow: setup
	@$(IN_ENV) python -m pytest test -m slow -s $(PYTEST_ARGS)

run: setup
	@$(IN_ENV) python -m bracing_bringup.paper_run --output out

bench: setup
	@$(IN_ENV) pip install --quiet --disable-pip-version-check -r requirements-bench.lock
	@$(IN_ENV) python bench/run.py --output bench/latest.json

# Re-pin after editing requirements.in (needs the registries).
lock:
	rm -rf /tmp/bracing-lock-venv && python3 -m venv /tmp/bracing-lock-venv
	/tmp/bracing-lock-venv/bin/pip install --report /tmp/bracing-lock-report.json -r requirements.in
	python3 tools/lock.py /tmp/bracing-lock-report.json > requirements.lock

clean:
	rm -rf build install log build.log out docs/_build
