# prodmaps — two commands do all the set-up on a fresh machine:
#   make reproduce   create .venv, install, regenerate every notebook into $(OUT) and write its
#                    report beside the results ($(OUT)/paper/REPORT.md); paper/ is left alone
#   make publish     the committed paper/REPORT.md(.html) and paper/report_figures/ from $(OUT)/paper
#                    (refuses a partial run; ALLOW_PARTIAL=1 publishes one and says what is partial)
#   make test        create/reuse .venv, run ruff, the workflow lint and the whole test suite
#                    (with the doctests and the docs build, tests/docs/)
#   make docs        the documentation site into docs/_build/html (DOCS_RUNS=results/smoke for
#                    the executed smoke notebooks in the gallery; nothing is executed)
PYTHON ?= python3
VENV   ?= .venv
PY     := $(VENV)/bin/python
OUT    ?= results
PROFILE ?= paper
JOBS   ?= 1
DOCS_RUNS ?=
ALLOW_PARTIAL ?=
PYTEST_ARGS ?=

.PHONY: reproduce reproduce-smoke update-baselines report publish claims test lint bench bench-quick venv clean-venv \
	strip-notebooks docs

venv: $(VENV)/.installed

# requirements-lock.txt: the exact versions that made the baselines, as constraints over
# pyproject.toml's ranges (a library install, `pip install .`, takes the ranges only)
$(VENV)/.installed: pyproject.toml requirements-lock.txt
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -c requirements-lock.txt -e ".[test,bench,docs]"
	$(PY) -m ipykernel install --sys-prefix --name python3 >/dev/null
	@touch $@

reproduce: venv
	$(PY) -m prodmaps reproduce --profile $(PROFILE) --out $(OUT) --jobs $(JOBS)

reproduce-smoke: venv
	$(PY) -m prodmaps reproduce --profile smoke --out $(OUT) --jobs $(JOBS)

update-baselines: venv
	$(PY) -m prodmaps reproduce --profile smoke --out $(OUT) --jobs $(JOBS) --update-baselines --force

report: venv
	$(PY) -m prodmaps report $(OUT)/$(PROFILE)

publish: venv
	$(PY) -m prodmaps publish $(OUT)/paper $(if $(ALLOW_PARTIAL),--allow-partial)

claims: venv
	$(PY) -m prodmaps claims $(OUT)/$(PROFILE)

lint: venv
	$(VENV)/bin/ruff check prodmaps tests benchmarks data_scripts notebooks
	$(VENV)/bin/actionlint -shellcheck= -pyflakes= .github/workflows/ci.yml

docs: venv
	PRODMAPS_DOCS_RUNS="$(DOCS_RUNS)" $(PY) -m sphinx -W --keep-going -q -b html docs docs/_build/html

test: venv lint
	$(PY) -m pytest -q $(PYTEST_ARGS)

bench: venv
	$(PY) benchmarks/run.py --out benchmarks/results

bench-quick: venv
	$(PY) benchmarks/run.py --quick --out $(or $(TMPDIR),/tmp)/prodmaps-bench-quick

strip-notebooks: venv
	$(PY) -m prodmaps.pipeline.notebooks strip notebooks/*.ipynb

clean-venv:
	rm -rf $(VENV)
