# Two commands set up a fresh machine: `make demo` and `make test`.
PY ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test test-slow bench templates clean system-deps

$(STAMP): pyproject.toml
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	$(BIN)/pip install --quiet -e '.[dev]'
	touch $(STAMP)

# FreeCAD 0.20 (freecadcmd) for the workbench tests and as an independent STEP reader, Xvfb for
# its GUI's test;
# Chromium and its WebDriver for the annotation page's browser test (Selenium drives it).
system-deps:
	@command -v freecadcmd >/dev/null 2>&1 || { \
	  echo "installing freecad-python3 (Debian) ..."; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq freecad-python3 >/dev/null; }
	@command -v xvfb-run >/dev/null 2>&1 || { \
	  echo "installing xvfb (Debian) ..."; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq xvfb xauth >/dev/null; }
	@{ command -v chromium >/dev/null 2>&1 && command -v chromedriver >/dev/null 2>&1; } || { \
	  echo "installing chromium and chromium-driver (Debian) ..."; \
	  apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null; }

# Two test workers on two cores: one BLAS/OpenMP thread each (more oversubscribe the cores and
# make the numerical tests several times slower).
test: $(STAMP) system-deps
	OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1 $(BIN)/python -m pytest -q -n 2 --durations=15

test-slow: $(STAMP) system-deps
	$(BIN)/python -m pytest -q -m slow

demo: $(STAMP) system-deps
	$(BIN)/carbody demo --out out

templates: $(STAMP)
	$(BIN)/carbody templates build --out templates_step

bench: $(STAMP)
	@for b in benchmarks/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done

clean:
	rm -rf $(VENV) out .pytest_cache
