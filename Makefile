# The two commands of README.md:
#   make sweep   set everything up, then run the default sweep on the built-in model
#   make test    set everything up, then run every test (cargo test and pytest)
# PUPPER_PROFILE=debug builds the module and binary without optimisation.
# PUPPER_EXTRAS=gpu,ray makes `make setup` install optional extras too (gpu:
# MuJoCo Warp for --backend warp; ray: Ray for --ray; tune: Optuna for
# pupper tune; fit: mujoco.sysid's dependencies for pupper fit); `make test` installs
# every extra, as its tests run them for real, and dev (mypy, which checks
# the stubs against examples/typed_tour.py).
SHELL := /bin/bash
ROOT := $(abspath .)
export PUPPER_PROFILE ?= release
export PYO3_PYTHON := $(ROOT)/.venv/bin/python
# Offscreen rendering in tests and plots, without a display.
export MUJOCO_GL ?= egl
PUPPER := target/$(PUPPER_PROFILE)/pupper
PY := .venv/bin/python

.PHONY: setup sweep test test-rust test-python wheel bench bench-gpu bench-ray lint lock clean

setup:
	@bash scripts/setup.sh

sweep: setup
	$(PUPPER) sweep --grid kp=10,30,60,120 --grid kd=0.5,1,2,5

# every optional extra: the tests run the warp backend (on Warp's CPU device),
# --ray (on a two-node Ray cluster over loopback, in its own namespaces),
# tune (Optuna) and fit (mujoco.sysid) for real; dev adds mypy for
# tests/test_types.py
test: export PUPPER_EXTRAS := gpu,ray,dev,tune,fit
test: setup test-rust test-python

test-rust:
	cargo test --workspace --release

# pytest-xdist (the dev extra) runs the tests on every core: most of them
# wait on one single-threaded process. Tests sharing a module's fixture stay
# on one worker (tests/conftest.py). PUPPER_TEST_WORKERS=N sets the workers,
# 0 runs them all in one process, as does a venv without xdist. (Expanded
# when the recipe runs, after setup has installed the extras.)
PUPPER_TEST_WORKERS ?= auto
XDIST = $(shell [ "$(PUPPER_TEST_WORKERS)" != 0 ] && $(PY) -c 'import xdist' 2>/dev/null \
	  && echo "--numprocesses $(PUPPER_TEST_WORKERS) --dist loadgroup")
test-python:
	PUPPER_BIN=$(ROOT)/$(PUPPER) $(PY) -m pytest $(XDIST) tests

wheel: setup
	cd python && ../.venv/bin/maturin build --release -o ../dist

bench: setup
	$(PY) benches/bench_sweep.py
	$(PY) benches/bench_lab.py
	$(PY) benches/bench_replicates.py
	$(PY) benches/bench_response.py

# the warp backend against a bare MuJoCo Warp loop and the cpu backend
bench-gpu: export PUPPER_EXTRAS := gpu
bench-gpu: setup
	$(PY) benches/bench_gpu.py

# --ray on a loopback cluster of this machine's cores against a local run
bench-ray: export PUPPER_EXTRAS := ray
bench-ray: setup
	$(PY) benches/bench_ray.py

lint:
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets --release -- -D warnings

lock:
	bash scripts/lock.sh

clean:
	rm -rf target .venv runs dist
