# Developer entry points. Assumes only python3, cargo and access to PyPI / crates.io.
#   make venv     .venv with maturin, numpy, pytest, pytest-xdist, mypy, ruff, scipy (tests: derivatives, t quantiles),
#                 matplotlib and pyarrow (the plot and parquet extras, tested) (from PyPI)
#   make develop  build the extension (release; VEHID_CARGO_PROFILE=ci as `test` and `demo` build it) into .venv, editable
#   make demo     build with the plot extra (matplotlib), reproduce the thesis (--quick) into report/, print its path
#   make docs     the documentation site into site/ (open site/index.html): mkdocs-material with the
#                 tools pinned in docs/requirements.txt, every page's examples run at build time,
#                 the Python API from the docstrings, rustdoc (cargo doc) under site/rustdoc/, the
#                 thesis-equation index generated from the sources; --strict: any warning fails it
#   make test     lint, every Rust test (unit, integration, bins, benches in test mode, examples,
#                 doctests), the no_std build, pytest on the fresh extension, stub check
#                 (clippy -D warnings runs inside those builds: see `test:`); the fleet report's
#                 browser test in a headless Chromium (`make browser` installs Debian's as root)
#                 (MATURIN_FLAGS=... and CARGO_TEST_FLAGS=... pass options to the extension's and the Rust
#                 tests' builds, e.g. --timings for cargo's report of where the compile goes)
#   make browser  Chromium for that test, from apt-get when there is none (root only)
#   make lint     cargo fmt --check, clippy -D warnings, ruff (`make test` lints the same, in its builds)
#   make install-check  `pip install .` into a fresh venv in a temp dir (the pyproject backend
#                 builds through maturin), then `vehid --help` and `vehid simulate | vehid
#                 identify`, which must report xi (slow: a full release build; not in `test`)
#   make wheel-check  the wheel as the release workflow builds it (maturin build --release, into dist/),
#                 installed into a fresh venv: the README's examples run from outside the tree (not in `test`)
#   make bench-python   Python-level overhead of KalmanIdentifier.update()/fit() against the
#                 budgets (RUST_NS=<ns per sample from `cargo bench`> to compare with a measured figure)
#   make bench-fit      Python fit() against the Rust update (fixed and heap forms) on the same data,
#                 in one run, with the ratio (budget 1.25x)
#   make bench-peers    the same quarter-car data, then half-car data, through filterpy, padasip,
#                 statsmodels, numpy (RLS loop, lstsq), vehid (update/fit) and a plain C loop
#                 (benches/peers/rls.c): agreement of θ first, then ns/sample and ratios; the peers live in their own
#                 .venv-peers (never vehid dependencies) with a vehid wheel built for it
#   make bench-budgets  every budget of benches/budgets.toml (runs the criterion benches they use
#                 BUDGET_RUNS=3 times and keeps the best, measures the Python overhead) with the
#                 figure and the ratio to the plain C loop; reports, does not fail (STRICT=1: fail on a miss)
#   make bench-check    regression gate: instructions per update under valgrind's callgrind
#                 (release build) against benches/callgrind_baseline.json; fails on > 5 % growth
#   make bench-check-update  rewrite that baseline deliberately (see below)
#   make soak     f32 soak: 10^8 square-root-form updates per run, quarter and half car,
#                 excited and still, states x1/x10/x0.1: P positive definite and theta finite at every
#                 check, xi within 10x of f64; a table at the end (SOAK_UPDATES=1e6 for a short run;
#                 about an hour in full; not in `test`)
#   make fuzz     the fuzz harness (tests/fuzz_harness.py): FUZZ_CALLS=1000000 seeded calls of the
#                 whole Python API with random shapes, dtypes, NaN/inf, huge and subnormal values, None and
#                 strings; 0 panics, only ValueError/TypeError/VehidError/MemoryError/OverflowError, every
#                 rejected call leaves its object bit for bit unchanged; progress lines, the seed
#                 (FUZZ_SEED=1) and a summary (about 10 minutes here; `make test` runs 10,000 calls of it)
#   make mutants  mutation testing of vehid-core (cargo-mutants): MUTANTS_FILE (default identify/**), one
#                 round-robin sample MUTANTS_SHARD=K/N (default 0/40, about 130 mutants, 1-2 min each
#                 here; MUTANTS_SKIP_BASELINE=1 skips the unmutated run on a tree known to pass); the caught
#                 fraction with its 95 % interval; fails on a survivor not accepted with a
#                 reason in benches/mutants_accepted.txt (not in `test`)
#   make mutants-uncovered  the mutants of MUTANTS_FILE on lines no Rust test runs (LLVM coverage of
#                 the Rust tests, about 5 min): certain survivors, listed by function (not in `test`)
#   make clean    remove build products and the venv

PYTHON ?= python3
VENV   := .venv
VBIN   := $(VENV)/bin
CARGO  ?= cargo

.PHONY: venv browser develop demo docs test lint lint-fast test-rust test-python python-checks install-check wheel-check bench-python bench-fit bench-peers bench-budgets bench-check bench-check-update soak fuzz mutants mutants-uncovered clean

venv: $(VENV)/.installed

# pytest-xdist runs the suite on every core (`-n auto`): most tests wait on the extension with
# the GIL released or on subprocesses, so two workers halve pytest's time here. The stamp
# depends on this Makefile, so that a venv made before a tool was added gets it. The extras'
# packages (matplotlib for vehid[plot], pyarrow for vehid[parquet], pyarrow and dask[distributed] for
# vehid[fleet]: its tests start a real Dask cluster) come too: without them a
# clean `make test` skipped the 13 tests of the plots and of Parquet input. statsmodels is the
# independent reference of the residual diagnostics and the realistic sensors' intervals.
# Playwright drives a headless Chromium for the fleet report's browser test (`make browser`).
$(VENV)/.installed: Makefile
	$(PYTHON) -m venv $(VENV)
	$(VBIN)/python -m pip install --quiet maturin numpy pytest pytest-xdist mypy ruff scipy statsmodels matplotlib pyarrow "dask[distributed]" rosbags playwright
	touch $@

# The browser of `tests/test_fleet_browser.py` (the fleet report rendered by a real headless
# Chromium): the system's, or Debian's `chromium` package when there is none and this runs as
# root with apt-get (about 35 s here, once); Playwright drives it by its path, so Playwright's
# own browser download is never needed. Otherwise it says so, and the test is skipped with the
# same reason.
browser:
	@found=$$(command -v chromium || command -v chromium-browser || command -v google-chrome); \
	if [ -n "$$found" ]; then \
	  echo "browser: $$found"; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
	  echo "browser: installing Debian's chromium (apt-get) for the report's browser test"; \
	  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null \
	    || { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null; }; \
	else \
	  echo "browser: no Chromium on PATH and no root apt-get to install one: tests/test_fleet_browser.py will be skipped"; \
	fi

# The Cargo profile of the extension: release, but `make test` and `make demo` build the `ci`
# profile (Cargo.toml: the test profile, with the size table's crate at opt-level 1 and the
# binding and the thesis reproduction at 3: the same results bit for bit, compiled once for the
# Rust tests and the extension alike, slower per sample). The scripts that build Rust binaries
# for the tests (the golden θ, the callgrind gate's own test) read it too, so that they reuse
# that build. What is timed uses release.
VEHID_CARGO_PROFILE ?= release
export VEHID_CARGO_PROFILE

# A stale extension module in python/vehid/ would shadow the fresh build: remove it first.
# Cargo's progress is shown (the first build takes minutes); pip stays quiet (PIP_QUIET).
develop: venv
	rm -f python/vehid/*.so python/vehid/*.pyd
	@echo "develop: building the extension (profile $(VEHID_CARGO_PROFILE), linted; the first build compiles the dependencies, then"
	@echo "develop: vehid-runtime and vehid-py, each several minutes on two cores with no output while they compile)"
	env -u CONDA_PREFIX VIRTUAL_ENV="$(abspath $(VENV))" PIP_QUIET=1 $(VBIN)/maturin develop --profile $(VEHID_CARGO_PROFILE) $(MATURIN_FLAGS)

# The plot extra (vehid[plot] = matplotlib) into the same venv, then the quick reproduction.
demo: develop
	$(VBIN)/python -m pip install --quiet matplotlib
	$(VBIN)/vehid reproduce --quick --out report/
	@echo "report: $(abspath report/index.html) (and report/index.md)"

# cargo doc first: the site takes target/doc in as site/rustdoc/ (docs/hooks/site.py), so that
# its links are checked like the others. NO_MKDOCS_2_WARNING silences mkdocs-material's notice
# about MkDocs 2.0 (advice on the tool's future, not about this site).
docs: develop
	$(VBIN)/python -m pip install --quiet -r docs/requirements.txt
	RUSTDOCFLAGS="-D warnings" $(CARGO) doc --no-deps -p vehid-core -p vehid-thesis
	NO_MKDOCS_2_WARNING=1 $(VBIN)/mkdocs build --strict --site-dir site
	@echo "docs: $(abspath site/index.html)"

# Clippy runs inside the builds `make test` makes anyway, as `cargo clippy` itself runs it:
# clippy-driver as the workspace crates' compiler (RUSTC_WORKSPACE_WRAPPER; the dependencies
# are compiled by rustc as always) with `-D warnings` (CLIPPY_ARGS, clippy's own way of passing
# its arguments). So every workspace target is linted while it is compiled for its test: the
# library, tests, bins, benches and examples in test-rust, the no_std build, and vehid-py in the
# extension's build. A separate `cargo clippy` would check the whole dependency tree a
# third time (about 2 minutes of a clean `make test` here). `make lint` still runs it on its own.
# The wrapper is part of cargo's fingerprint of the workspace crates, so `develop` (and with it
# `make demo`) compiles the extension the same way when clippy is installed: `make demo` then
# `make test` (or the other way round) builds the extension once. Without clippy-driver,
# `develop` uses rustc alone (`make test` then needs clippy, and rebuilds the workspace crates).
#
# One build, in one profile (`ci`) and one target directory, serves the extension and the Rust
# tests: the extension first (pytest waits for it), then the Rust tests' build and runs beside
# pytest and the lints. The Rust tests' build compiles only their own targets (the libraries
# and the dependencies are the extension's, when the features resolve alike: see
# `CARGO_SELECT`). Two cargos in one target directory take turns at its lock while they
# compile (the callgrind gate's and the golden θ's tests wait for the Rust tests' build), not
# while tests run.
#
# Incremental compilation is off for these builds (cargo turns it on in dev):
# on a clean build it writes a cache that only a later edit reads, and it costs a quarter more
# CPU (vehid-core's unit-test target: 156 s of CPU without, 212 s with, on this machine). An
# edit-test loop may want it back: `CARGO_INCREMENTAL=1 make test`.
CLIPPY_ARGS_DENY := -D__CLIPPY_HACKERY__warnings__CLIPPY_HACKERY__
test: export CARGO_INCREMENTAL ?= 0
test demo: export VEHID_CARGO_PROFILE := ci
test: export RUSTC_WORKSPACE_WRAPPER := clippy-driver
test: export CLIPPY_ARGS := $(CLIPPY_ARGS_DENY)
develop: export RUSTC_WORKSPACE_WRAPPER := $(shell command -v clippy-driver >/dev/null 2>&1 && echo clippy-driver)
develop: export CLIPPY_ARGS := $(CLIPPY_ARGS_DENY)
test: export VEHID_TEST_PROFILE = $(VEHID_CARGO_PROFILE)
test:
	@$(MAKE) --no-print-directory -j2 develop browser
	@$(MAKE) --no-print-directory -j2 lint-fast test-rust python-checks

# `make lint` on its own: clippy over every target (`make test` lints inside its builds).
lint: lint-fast
	$(CARGO) clippy --workspace --all-targets -- -D warnings

lint-fast: venv
	$(CARGO) fmt --all --check
	$(VBIN)/ruff check python tests benches

# The Rust tests' packages: the workspace but vehid-runtime (pytest tests it through the
# extension; its 16 x 4 size table would only be compiled once more for a test harness).
# vehid-py stays in the selection for the features alone (its lib has test, doctest and bench
# off, so none of it is compiled here): the dependencies then resolve as in the extension's
# build, and `make test` compiles them once. vehid-core's own default feature is off as in
# that build (the feature set is part of a crate's fingerprint).
CARGO_SELECT := --workspace --exclude vehid-runtime --no-default-features --features vehid-core/std
# The Rust tests' profile: cargo's test profile (`make test-rust`), `ci` in `make test`.
VEHID_TEST_PROFILE ?= test
test-rust:
	$(CARGO) test --profile $(VEHID_TEST_PROFILE) $(CARGO_SELECT) --tests --benches --examples $(CARGO_TEST_FLAGS)
	$(CARGO) test --profile $(VEHID_TEST_PROFILE) $(CARGO_SELECT) --doc
	$(CARGO) check -p vehid-core --no-default-features
	$(CARGO) check -p vehid-core --no-default-features --features persist

# pytest on the extension `develop` built, the stub check, mypy.
test-python: develop
	@$(MAKE) --no-print-directory python-checks

python-checks: venv
	$(VBIN)/python -m pytest -q -n auto tests
	$(VBIN)/python -m mypy.stubtest vehid._vehid
	$(VBIN)/python -m mypy python/vehid

# Exactly what a user does on a clean machine; run from a temp dir so that the source tree's
# python/vehid cannot be imported instead of the installed package.
install-check:
	@set -eu; tmp=$$(mktemp -d); trap 'rm -rf "$$tmp"' EXIT; \
	echo "install-check: pip install . into $$tmp/venv"; \
	$(PYTHON) -m venv "$$tmp/venv"; \
	env -u CONDA_PREFIX -u VIRTUAL_ENV "$$tmp/venv/bin/python" -m pip install --quiet "$(CURDIR)"; \
	cd "$$tmp"; \
	"$$tmp/venv/bin/vehid" --help > /dev/null; \
	out=$$("$$tmp/venv/bin/vehid" simulate --model quarter --n 2000 -o - | "$$tmp/venv/bin/vehid" identify - --model quarter); \
	echo "$$out"; \
	case "$$out" in *"xi (Eq 3.17"*) echo "install-check: ok";; \
	  *) echo "install-check: FAILED: no xi in the output of vehid identify" >&2; exit 1;; esac

# The wheel as the release workflow builds it (`maturin build --release`, abi3), installed into
# a fresh venv with pip alone: from outside the source tree the README's Python examples run,
# its console examples print what it shows, and simulate | identify reports xi.
wheel-check: venv
	rm -rf dist
	env -u CONDA_PREFIX $(VBIN)/maturin build --release --out dist
	VEHID_WHEEL="$$(ls dist/vehid-*.whl)" $(VBIN)/python -m pytest -q -rs tests/test_install_check.py -k wheel

# Python fit() against the Rust update on the same data, in one run (budget: <= 1.25x).
bench-fit: develop
	$(CARGO) build -q --release -p vehid-benches --bin time_updates
	$(VBIN)/python benches/python/fit_vs_rust.py

RUST_NS ?=
bench-python: develop
	$(VBIN)/python benches/python/overhead.py $(if $(RUST_NS),--rust-ns $(RUST_NS))

PEERS_VENV := .venv-peers
PEERS_PKGS := filterpy padasip statsmodels numpy

$(PEERS_VENV)/.installed:
	$(PYTHON) -m venv $(PEERS_VENV)
	$(PEERS_VENV)/bin/python -m pip install --quiet $(PEERS_PKGS)
	touch $@

# vehid goes into .venv-peers as a freshly built wheel (not editable: `maturin develop` would
# write its .so into python/vehid, shared with .venv).
bench-peers: venv $(PEERS_VENV)/.installed
	rm -rf target/peers-wheel
	env -u CONDA_PREFIX $(VBIN)/maturin build --release --quiet -o target/peers-wheel
	$(PEERS_VENV)/bin/python -m pip install --quiet --force-reinstall --no-deps target/peers-wheel/vehid-*.whl
	$(PEERS_VENV)/bin/python benches/peers/run_peers.py --json target/peers/peers.json

BUDGET_BENCHES := update_f64/(quarter|half)/kalman_(rows|shared)|update_f64/quarter/(structured_(rows|physical)|iv_physical_road|state_filter_realistic)|simulate_f64/(quarter/|full/drive)
STRICT ?=
BUDGET_RUNS ?= 3
bench-budgets: develop
	rm -rf target/bench/criterion-runs
	@for i in $$(seq 1 $(BUDGET_RUNS)); do \
	  echo "bench-budgets: criterion run $$i of $(BUDGET_RUNS)"; \
	  $(CARGO) bench -p vehid-benches --bench identify -- '$(BUDGET_BENCHES)' > target/bench-run.log 2>&1 \
	    || { cat target/bench-run.log; exit 1; }; \
	  grep -E '^(update|simulate)|time:' target/bench-run.log | grep -v '%' | sed 's/^/  /'; \
	  mkdir -p target/bench/criterion-runs/$$i; \
	  cp -r target/criterion/update_f64 target/criterion/simulate_f64 target/bench/criterion-runs/$$i/; \
	done
	$(VBIN)/python benches/python/overhead.py --json target/bench/python_overhead.json
	$(VBIN)/python benches/check_budgets.py $(if $(STRICT),--strict) \
	  $(foreach i,$(shell seq 1 $(BUDGET_RUNS)),--criterion target/bench/criterion-runs/$(i))

# Instruction counts are deterministic for a given binary and input, so the gate is stable on a
# noisy machine. To change the baseline deliberately (a change meant to cost more, a speed-up
# to keep, a new rustc or valgrind): `make bench-check-update`, read the old -> new counts it
# prints, and commit benches/callgrind_baseline.json with the change, saying why.
# (benches/callgrind_check.py's docstring has the details; --bench NAME limits it to one bench.)
bench-check:
	$(PYTHON) benches/callgrind_check.py

bench-check-update:
	$(PYTHON) benches/callgrind_check.py --update

# The f32 soak, built in release (benches/src/bin/soak.rs documents the runs and the checks; exit
# status 1 on a failed check). SOAK_CHECK, SOAK_THREADS and SOAK_ONLY pass through the environment.
SOAK_UPDATES ?= 1e8
soak:
	SOAK_UPDATES=$(SOAK_UPDATES) $(CARGO) run -q --release -p vehid-benches --bin soak

# The fuzz harness on the fresh extension (exit status 1 on a failure, which names the seed
# and episode that reproduce it: python tests/fuzz_harness.py --seed S --episode K).
FUZZ_CALLS ?= 1000000
FUZZ_SEED ?= 1
fuzz: develop
	FUZZ_CALLS=$(FUZZ_CALLS) FUZZ_SEED=$(FUZZ_SEED) $(VBIN)/python tests/fuzz_harness.py

# Mutation testing: cargo-mutants on MUTANTS_FILE, one round-robin shard at a time
# (a mutant costs about a minute here; benches/mutants_check.py explains the sampling), the
# caught fraction with its 95 % interval, and a failure for any survivor not accepted with a
# reason in benches/mutants_accepted.txt. Installs cargo-mutants (crates.io) when missing.
# MUTANTS_ITERATE=1 tests again only what the last run of the shard did not catch.
MUTANTS_FILE ?= crates/vehid-core/src/identify/**
MUTANTS_SHARD ?= 0/40
MUTANTS_ITERATE ?=
mutants:
	@command -v cargo-mutants > /dev/null || $(CARGO) install --locked cargo-mutants
	$(PYTHON) benches/mutants_check.py --file '$(MUTANTS_FILE)' --shard $(MUTANTS_SHARD) $(if $(MUTANTS_ITERATE),--iterate) $(if $(MUTANTS_SKIP_BASELINE),--skip-baseline)

# The mutants on lines no Rust test executes (benches/uncovered_mutants.py): one coverage run of
# the Rust tests instead of a mutant build each. Installs cargo-mutants and llvm-tools when missing.
mutants-uncovered:
	@command -v cargo-mutants > /dev/null || $(CARGO) install --locked cargo-mutants
	$(PYTHON) benches/uncovered_mutants.py --file '$(MUTANTS_FILE)'

clean:
	rm -f python/vehid/*.so python/vehid/*.pyd
	rm -rf $(VENV) $(PEERS_VENV) dist site .pytest_cache .mypy_cache
	find python tests -name __pycache__ -type d -prune -exec rm -rf {} +
	$(CARGO) clean
