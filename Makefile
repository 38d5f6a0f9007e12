# ilc-analysis: every command runs inside .venv, created on first use.
PYTHON ?= python3.11
VENV := .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed
OUT ?= results

.PHONY: reproduce test bench lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[dev]"
	$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null
	touch $(STAMP)

reproduce: $(STAMP)
	$(VENV)/bin/ilc-analysis reproduce --out $(OUT)

test: $(STAMP)
	MPLBACKEND=Agg $(PY) -m pytest -q -p no:cacheprovider

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do MPLBACKEND=Agg $(PY) $$b || exit 1; done

lint: $(STAMP)
	$(VENV)/bin/ruff check ilc_analysis tests benchmarks

clean:
	rm -rf $(VENV) $(OUT) build *.egg-info
