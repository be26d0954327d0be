# Developer entry points. Assumes only python3, cargo and access to PyPI / crates.io.
#   make venv     .venv with maturin, numpy, pytest, mypy (from PyPI)
#   make develop  build the extension (release) into .venv, editable
#   make demo     simulate the quarter car and compare with the analytic standard deviations
#   make test     Rust tests, no_std build, benches compile, pytest, stub check
#   make clean    remove build products and the venv

PYTHON ?= python3
VENV   := .venv
VBIN   := $(VENV)/bin
CARGO  ?= cargo

.PHONY: venv develop demo test test-rust test-python clean

venv: $(VENV)/.installed

$(VENV)/.installed:
	$(PYTHON) -m venv $(VENV)
	$(VBIN)/python -m pip install --quiet maturin numpy pytest mypy
	touch $@

# A stale extension module in python/vehid/ would shadow the fresh build: remove it first.
develop: venv
	rm -f python/vehid/*.so python/vehid/*.pyd
	env -u CONDA_PREFIX VIRTUAL_ENV="$(abspath $(VENV))" $(VBIN)/maturin develop --release --quiet

demo: develop
	$(VBIN)/vehid demo

test: test-rust test-python

test-rust:
	$(CARGO) test --workspace
	$(CARGO) build -p vehid-core --no-default-features
	$(CARGO) test --benches

test-python: develop
	$(VBIN)/python -m pytest -q tests
	$(VBIN)/python -m mypy.stubtest vehid._vehid
	$(VBIN)/python -m mypy python/vehid

clean:
	rm -f python/vehid/*.so python/vehid/*.pyd
	rm -rf $(VENV) dist .pytest_cache .mypy_cache
	find python tests -name __pycache__ -type d -prune -exec rm -rf {} +
	$(CARGO) clean
