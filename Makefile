# The commands of the README. Both bootstrap .venv on a fresh machine first.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.hydrojam-installed
DEMO_OUT ?= demo-out

.PHONY: demo test docs bench clean

$(STAMP): pyproject.toml tools/bootstrap.sh
	PYTHON=$(PYTHON) bash tools/bootstrap.sh $(VENV)
	touch $(STAMP)

# The demo takes about 2 minutes on 2 cores (2.2 min measured after the installation): the
# swelling curve and the paper's temperature and strain-limit thickness sweeps (quick), 3
# replicas a point so that its verdicts are read against their spread; the particle-layer sweep
# (its 19-layer point alone takes about 10 minutes) is added by the command it prints.
demo: $(STAMP)
	mkdir -p $(DEMO_OUT)
	$(BIN)/hydrojam swell --t-min 275 --t-max 315 --t-step 2.5 --plot $(DEMO_OUT)/swelling.png
	$(BIN)/hydrojam reproduce --quick --replicas 3 --sweep temperature --sweep strain_limit_thickness -o $(DEMO_OUT)/reproduce
	@echo "report: $(DEMO_OUT)/reproduce/report.md (figures in $(DEMO_OUT)/reproduce/figures/)"
	@echo "the particle-layer sweep (tens of minutes more on 2 cores): $(BIN)/hydrojam reproduce --quick --replicas 3 -o $(DEMO_OUT)/reproduce"

# -n auto: one pytest worker per CPU (the slow contact tests then run side by side)
test: $(STAMP)
	$(BIN)/python -m pytest -n auto

# the documentation site (Sphinx, MyST pages, API reference from the docstrings), warnings as errors
docs: $(STAMP)
	$(BIN)/sphinx-build -W --keep-going -q -b html docs docs/_build/html
	@echo "site: docs/_build/html/index.html"

bench: $(STAMP)
	$(BIN)/python benchmarks/fe_core.py
	$(BIN)/python benchmarks/actuator.py

clean:
	rm -rf $(VENV) $(DEMO_OUT) build docs/_build src/*.egg-info
