# Two commands do all set-up on a fresh machine (Debian, Python 3.11):
#   make demo   - the main job: the paper's reference experiment end to end
#   make test   - the test suite (what CI runs through .ci/run)
PYTHON ?= python3
VENV := .venv
STAMP := $(VENV)/.installed-stamp
OUT ?= out/demo

.PHONY: demo test setup clean chromium

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(VENV)/bin/python -m pip install --quiet --upgrade pip
	$(VENV)/bin/python -m pip install --quiet -e ".[test]"
	$(VENV)/bin/platebench info >/dev/null
	touch $(STAMP)

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
	$(VENV)/bin/python -m pytest -q

clean:
	rm -rf $(VENV) out
