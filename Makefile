# The two commands of README.md:
#   make sweep   set everything up, then run the default sweep on the built-in model
#   make test    set everything up, then run every test (cargo test and pytest)
# PUPPER_PROFILE=debug builds the module and binary without optimisation.
SHELL := /bin/bash
ROOT := $(abspath .)
export PUPPER_PROFILE ?= release
export PYO3_PYTHON := $(ROOT)/.venv/bin/python
# Offscreen rendering in tests and plots, without a display.
export MUJOCO_GL ?= egl
PUPPER := target/$(PUPPER_PROFILE)/pupper
PY := .venv/bin/python

.PHONY: setup sweep test test-rust test-python wheel bench lint lock clean

setup:
	@bash scripts/setup.sh

sweep: setup
	$(PUPPER) sweep --grid kp=10,30,60,120 --grid kd=0.5,1,2,5

test: setup test-rust test-python

test-rust:
	cargo test --workspace --release

test-python:
	PUPPER_BIN=$(ROOT)/$(PUPPER) $(PY) -m pytest tests

wheel: setup
	cd python && ../.venv/bin/maturin build --release -o ../dist

bench: setup
	$(PY) benches/bench_sweep.py
	$(PY) benches/bench_lab.py
	$(PY) benches/bench_replicates.py

lint:
	cargo fmt --all -- --check
	cargo clippy --workspace --all-targets --release -- -D warnings

lock:
	bash scripts/lock.sh

clean:
	rm -rf target .venv runs dist
