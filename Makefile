# Quick start: `make demo` and `make test`. Each sets up .venv itself (scripts/setup_env.sh).
PY := .venv/bin/python
# every test process gets its own DDS domain so parallel runs do not see each other
export ROS_DOMAIN_ID ?= 42

.PHONY: setup demo test lint bench clean

setup:
	@bash scripts/setup_env.sh

demo: setup
	$(PY) -m gait_biofeedback.cli demo

# the outer KILL timeout is the last guard: a hung rclpy process ignores SIGTERM
test: setup
	@bash scripts/setup_browser.sh
	$(PY) -m ruff check gait_biofeedback test benchmarks scripts
	timeout -s KILL 1200 $(PY) -m pytest -q

lint: setup
	$(PY) -m ruff check gait_biofeedback test benchmarks scripts

clean:
	rm -rf build .venv output .pytest_cache
