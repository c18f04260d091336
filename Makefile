# Quick start: `make demo` and `make test`. Each sets up .venv itself (scripts/setup_env.sh).
PY := .venv/bin/python
# every test process gets its own DDS domain so parallel runs do not see each other
export ROS_DOMAIN_ID ?= 42
# one BLAS thread per process: the core's small matrices gain nothing from more, and spinning threads on
# two busy cores slowed a test 35x (gait_biofeedback/__init__.py)
export OPENBLAS_NUM_THREADS ?= 1
export OMP_NUM_THREADS ?= 1

.PHONY: setup demo test lint docs bench clean

setup:
	@bash scripts/setup_env.sh

demo: setup
	$(PY) -m gait_biofeedback.cli demo

# the outer KILL timeout is the last guard: a hung rclpy process ignores SIGTERM. Two pytest-xdist
# workers, one test module each at a time (module fixtures built once), each on its own DDS domain
# (test/conftest.py): most tests wait on a live graph or a subprocess, so two cores run it in ~4.5 min
test: setup
	@bash scripts/setup_browser.sh
	$(PY) -m ruff check gait_biofeedback test benchmarks scripts
	timeout -s KILL 1200 $(PY) -m pytest -q -n 2 --dist loadfile

lint: setup
	$(PY) -m ruff check gait_biofeedback test benchmarks scripts

# the documentation site (mkdocs.yml) into build/docs; --strict: a warning (a broken link, a missing
# symbol of an API page) fails the build
docs: setup
	$(PY) -m mkdocs build --strict --site-dir build/docs

clean:
	rm -rf build .venv output .pytest_cache
