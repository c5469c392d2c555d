# Two commands: `make demo` and `make test`. Both create .venv and install what they need.
PYTHON ?= $(shell command -v python3.11 || command -v python3)
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: demo test bench fuzz clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test,bench,web]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/robo-comp demo --web 8080

test: $(STAMP)
	$(BIN)/python -m mypy  # the packages in pyproject's [tool.mypy]: every package and the top-level modules
	$(BIN)/python -m pytest -n 4  # four workers: most tests wait on real processes, not on a core

bench: $(STAMP)
	for b in bench/bench_*.py; do echo "== $$b"; $(BIN)/python $$b || exit 1; done
	# the figures at scale (docs/performance.md, "Figures that hold"), each beside its peer or baseline
	$(BIN)/python bench/bench_core.py --scale 2000 10000 --hosts 10 --stop-samples 300
	$(BIN)/python bench/bench_core.py --hosted 2000 --hosts 8 --stop-samples 300 --baseline b6547c5
	$(BIN)/python bench/bench_movingai.py --limit 100

# coverage-guided fuzzing with atheris (optional extra), both targets, 10 minutes
fuzz: $(STAMP)
	$(BIN)/python -m pip install --quiet -e '.[fuzz]'
	$(BIN)/python bench/fuzz_atheris.py --seconds 600

clean:
	rm -rf $(VENV) build *.egg-info
