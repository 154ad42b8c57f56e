# camtool: `make demo` runs the sample job, `make test` runs the tests.
# Both set up .venv first; set-up is idempotent (a stamp file records the
# hash of pyproject.toml, so a second run installs nothing).
PY      := .venv/bin/python

.PHONY: setup demo test samples bench clean

setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) -m camtool.cli run samples/sphere.toml -o out/sphere

test: setup
	$(PY) -m pytest -n 2 --dist loadfile

samples: setup   # every shipped sample end to end (CI runs it after `make test`)
	$(PY) -m pytest -n 2 -m samples tests/test_samples.py tests/test_same_bytes.py

bench: setup
	$(PY) -m pip install -q -e '.[bench,design]'   # the anchors: pyransac3d, roboticstoolbox, toppra, pymoo
	@for b in benchmarks/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf out .pytest_cache
