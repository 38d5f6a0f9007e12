# ilc-analysis: every command runs inside .venv, created on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= results

.PHONY: reproduce test bench lint clean docs docs-check typecheck wheel wheel-check notebooks

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null
	touch $(STAMP)

reproduce: $(STAMP)
	$(VENV)/bin/ilc-analysis reproduce --out $(OUT)

# the suite on every CPU, one test file per worker at a time (its module fixtures built once);
# a per-test time limit that fails a stuck test by name, the slowest tests listed at the end
# ([tool.pytest.ini_options] in pyproject.toml). TEST_WORKERS=0 runs it in one process.
TEST_WORKERS ?= auto
test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -p no:cacheprovider -n $(TEST_WORKERS) --dist loadfile

# every benchmark (BENCH_ARGS=--small: the test suite's small sizes); all run, the failed are named
BENCH_ARGS ?=
bench: $(STAMP)
	@failed=""; for b in benchmarks/bench_*.py; do echo "== $$b $(BENCH_ARGS)"; \
		MPLBACKEND=Agg ILC_PROGRESS=0 $(PY) $$b $(BENCH_ARGS) || failed="$$failed $$b"; done; \
	if [ -n "$$failed" ]; then echo "make bench: FAILED:$$failed" >&2; exit 1; fi

lint: $(STAMP)
	$(VENV)/bin/ruff check ilc_analysis tests benchmarks

# the documentation site, warnings as errors (docs/conf.py generates the API, CLI and example
# pages; the notebooks run once, cached by content in docs/_build/.jupyter_cache)
docs: $(STAMP)
	$(PY) -m sphinx -b html -W --keep-going -q docs docs/_build/html

# the built site (make docs first) shows what it must: titles, API and CLI pages, notebook figures,
# mathematics typeset offline in headless Chromium (Debian's chromium, installed here if missing:
# apt-get needs root, as CI runs)
docs-check:
	@command -v chromium >/dev/null || { apt-get update -qq && \
		DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }
	MPLBACKEND=Agg $(PY) -m pytest -q -p no:cacheprovider -m docs tests/test_docs_site.py

typecheck: $(STAMP)
	$(PY) -m mypy

wheel: $(STAMP)
	rm -rf build/dist
	$(PY) -m build --outdir build/dist .

# the wheel in a fresh venv (no source tree on the path), the core install without extras: the
# console command runs; no Dask, zarr or Jupyter; `study` names the extra it needs
WHEEL_VENV ?= build/wheel-venv
wheel-check: wheel
	rm -rf $(WHEEL_VENV)
	$(PYTHON) -m venv $(WHEEL_VENV)
	$(WHEEL_VENV)/bin/python -m pip install --quiet build/dist/*.whl
	cd $(WHEEL_VENV) && MPLBACKEND=Agg bin/ilc-analysis model --json > model.json
	$(WHEEL_VENV)/bin/python -c "import json,sys; d=json.load(open(sys.argv[1])); assert d['is_equilibrium'] and d['A'], d" $(WHEEL_VENV)/model.json
	cd $(WHEEL_VENV) && MPLBACKEND=Agg bin/ilc-analysis check --scenario paper -N 50 --json > check.json
	$(WHEEL_VENV)/bin/python -c "import json,sys; json.load(open(sys.argv[1]))" $(WHEEL_VENV)/check.json
	cd $(WHEEL_VENV) && bin/python -c "import ilc_analysis, pathlib; p = pathlib.Path(ilc_analysis.__file__).parent; assert 'site-packages' in str(p), p; assert (p / 'py.typed').is_file(); assert (p / 'paper' / 'paper.toml').is_file()"
	$(WHEEL_VENV)/bin/python -c "import importlib.util as u; extra = [m for m in ('dask', 'distributed', 'zarr', 'jupyterlab') if u.find_spec(m)]; assert not extra, f'the core install brings {extra}'"
	MPLBACKEND=Agg $(WHEEL_VENV)/bin/ilc-analysis study examples/studies/vertices.toml --out $(WHEEL_VENV)/study --serial --allow-code 2> $(WHEEL_VENV)/study.err; \
		test $$? -eq 2 && grep -q 'install ilc-analysis\[studies\]' $(WHEEL_VENV)/study.err || { cat $(WHEEL_VENV)/study.err; exit 1; }

# the notebooks in JupyterLab (the notebooks extra, which make installs)
notebooks: $(STAMP)
	$(VENV)/bin/jupyter lab notebooks/

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info docs/_build

# The two must-show studies (issue 15; ~1 h on 2 workers of this 2-core machine): results in
# $(OUT)/study_*, committed reports rewritten in examples/studies/{uncertainty,forgetting}/.
.PHONY: studies
studies: $(STAMP)
	MPLBACKEND=Agg $(VENV)/bin/ilc-analysis study examples/studies/uncertainty.toml --out $(OUT)/study_uncertainty --workers 2 --allow-code
	MPLBACKEND=Agg $(VENV)/bin/ilc-analysis study examples/studies/forgetting.toml --out $(OUT)/study_forgetting --workers 2 --allow-code
	MPLBACKEND=Agg $(PY) examples/studies/make_reports.py $(OUT)
