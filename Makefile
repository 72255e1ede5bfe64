# Two commands do all set-up on a fresh machine (Debian, Python 3.11):
#   make demo   - the main job: the paper's reference experiment end to end
#   make test   - the test suite (what CI runs through .ci/run)
# Both install the exact versions of requirements.lock (made by pip-tools from pyproject.toml),
# then the package itself without dependencies. `make lock` upgrades the lock (see README).
PYTHON ?= python3
VENV := .venv
STAMP := $(VENV)/.installed-stamp
OUT ?= out/demo
TOOLS := .venv-tools

.PHONY: demo test setup clean chromium lock

$(STAMP): pyproject.toml requirements.lock
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet -r requirements.lock
	$(VENV)/bin/python -m pip install --quiet --no-deps -e .
	$(VENV)/bin/platebench info --check-lock >/dev/null
	touch $(STAMP)

# Re-resolve every dependency to its newest release allowed by pyproject.toml and rewrite
# requirements.lock (pip-tools in its own venv); then `make test` and commit the lock.
lock:
	$(PYTHON) -m venv $(TOOLS)
	$(TOOLS)/bin/python -m pip install --quiet pip-tools
	$(TOOLS)/bin/pip-compile --quiet --upgrade --strip-extras --extra test --no-emit-index-url \
	  --no-emit-find-links --output-file requirements.lock pyproject.toml

setup: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/platebench demo --out $(OUT) --overwrite

# The report test screenshots the HTML with headless Chromium (Debian's package). Installing
# it is best effort: without it (no root, no apt) that one test is skipped with the reason.
chromium:
	@command -v chromium >/dev/null 2>&1 || { [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1 && \
	  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
	  || echo "note: chromium not installed; the report screenshot test will be skipped"; }

test: $(STAMP) chromium
	$(VENV)/bin/python -m pytest -q -n 2 --durations=15

clean:
	rm -rf $(VENV) $(TOOLS) out
