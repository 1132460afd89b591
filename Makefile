# Two entry points for a fresh machine with Python 3.10+ and pip: `make demo` and `make test`.
# Each creates .venv on first use and reinstalls when pyproject.toml changes.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin

.PHONY: demo test lint bench generated clean docs docs-serve docs-snippets

$(BIN)/.installed: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	$(BIN)/python -m compileall -q netcfg
	$(BIN)/python -c "import netcfg.emit; netcfg.emit.precompile_templates()"  # jinja compiles them once, not per build
	touch $@

demo: $(BIN)/.installed
	$(BIN)/netcfg check specs/cambada.yaml specs/allex2.yaml specs/ntua_sahr.yaml
	$(BIN)/netcfg build specs/allex2.yaml -o build/allex2
	$(BIN)/netcfg simulate build/allex2/runtime.json --duration 8s --log build/allex2/sim.log
	$(BIN)/netcfg run build/allex2/runtime.json --interface virtual --simulated-drives --cycles 100

test: $(BIN)/.installed
	$(BIN)/ruff check netcfg tests benchmarks docs/gen
	$(BIN)/mypy
	$(BIN)/mkdocs build --strict --quiet  # the site builds without a warning (a few seconds)
	# one worker per core (tests/test_layers.py runs the layer contracts, lint-imports, too); then the live masters on
	# the wall clock alone, with the cores to themselves (tests/conftest.py LIVE_MODULES)
	$(BIN)/python -m pytest -n auto --dist loadfile -m "not live"
	$(BIN)/python -m pytest -m live

lint: $(BIN)/.installed
	$(BIN)/ruff check netcfg tests benchmarks docs/gen
	$(BIN)/mypy
	$(BIN)/lint-imports --no-cache

# The documentation site (mkdocs.yml): built into build/site, served locally; nothing is hosted.
# Material's notice about its successor is printed on every build otherwise
export NO_MKDOCS_2_WARNING := 1

docs: $(BIN)/.installed
	$(BIN)/mkdocs build --strict

docs-serve: $(BIN)/.installed
	$(BIN)/mkdocs serve

# Writes the real output of the pages' captured commands and their figures into the pages (tests/test_docs.py
# fails while a page is not what this writes); review the diff before committing it.
docs-snippets: $(BIN)/.installed
	$(BIN)/python docs/gen/refresh.py

generated: $(BIN)/.installed
	for spec in specs/*.yaml; do $(BIN)/netcfg build $$spec || exit 1; done
	$(BIN)/python scripts/sim_fingerprints.py

bench: $(BIN)/.installed
	$(BIN)/python -c "import netcfg.emit; netcfg.emit.precompile_templates()"  # templates edited since installing
	$(BIN)/python benchmarks/bench_check.py
	$(BIN)/python benchmarks/bench_dbc.py  # check F.dbc against cantools' own load of the same file
	$(BIN)/python benchmarks/bench_build.py
	$(BIN)/python benchmarks/bench_sim.py
	$(BIN)/python benchmarks/bench_lsp.py  # warm re-checks inside the language server
	$(BIN)/python benchmarks/bench_master.py  # the live master's SYNC lateness, idle and with every core busy
	$(BIN)/python benchmarks/soundness.py --specs 2500
	NETCFG_CLOSURE_SPECS=300 $(BIN)/python -m pytest -q tests/test_closure_random.py  # the closure suite's long run

clean:
	rm -rf $(VENV) build *.egg-info
