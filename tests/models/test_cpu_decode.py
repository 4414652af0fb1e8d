"""The CPU decode attention equals transformers' sdpa attention, for every mask form it can be handed."""

from __future__ import annotations

import pytest

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")

from transformers.integrations.sdpa_attention import sdpa_attention_forward  # noqa: E402

from models import cpu_decode  # noqa: E402


class _Module(torch.nn.Module):
    def __init__(self, groups: int) -> None:
        super().__init__()
        self.num_key_value_groups = groups
        self.is_causal = True
        self.eval()


def _inputs(batch: int = 3, heads: int = 6, kv_heads: int = 2, q_len: int = 1, kv_len: int = 37, dim: int = 16):
    g = torch.Generator().manual_seed(0)
    q = torch.randn(batch, heads, q_len, dim, generator=g)
    k = torch.randn(batch, kv_heads, kv_len, dim, generator=g)
    v = torch.randn(batch, kv_heads, kv_len, dim, generator=g)
    return _Module(heads // kv_heads), q, k, v


def _left_padding_mask(batch: int, q_len: int, kv_len: int) -> torch.Tensor:
    """Row i cannot see its first 3*i columns (left padding), as transformers' sdpa mask says it."""
    mask = torch.ones(batch, 1, q_len, kv_len, dtype=torch.bool)
    for i in range(batch):
        mask[i, :, :, : 3 * i] = False
    return mask


@pytest.mark.parametrize("form", ["none", "bool", "additive"])
def test_decode_step_matches_sdpa(form: str):
    module, q, k, v = _inputs()
    mask = None
    if form != "none":
        mask = _left_padding_mask(q.shape[0], 1, k.shape[2])
        if form == "additive":
            mask = torch.zeros(mask.shape).masked_fill(~mask, torch.finfo(torch.float32).min)
    ours, _ = cpu_decode._decode_attention(module, q, k, v, mask, scaling=0.3)
    ref, _ = sdpa_attention_forward(module, q, k, v, mask, scaling=0.3)
    assert ours.shape == ref.shape == (q.shape[0], 1, q.shape[1], q.shape[3])
    torch.testing.assert_close(ours, ref, atol=1e-5, rtol=1e-5)


def test_padding_is_really_masked():
    module, q, k, v = _inputs()
    mask = _left_padding_mask(q.shape[0], 1, k.shape[2])
    changed = v.clone()
    changed[2, :, :6] = 1e4  # only columns row 2 may not see
    a, _ = cpu_decode._decode_attention(module, q, k, v, mask)
    b, _ = cpu_decode._decode_attention(module, q, k, changed, mask)
    torch.testing.assert_close(a, b)


def test_bf16_decode_step_is_close_to_sdpa():
    module, q, k, v = _inputs(batch=8, heads=9, kv_heads=3, kv_len=300, dim=64)
    q, k, v = q.bfloat16(), k.bfloat16(), v.bfloat16()
    mask = _left_padding_mask(8, 1, 300)
    ours, _ = cpu_decode._decode_attention(module, q, k, v, mask)
    ref, _ = sdpa_attention_forward(module, q, k, v, mask)
    torch.testing.assert_close(ours.float(), ref.float(), atol=2e-2, rtol=2e-2)


def test_prefill_and_uncovered_cases_take_the_sdpa_path():
    module, q, k, v = _inputs(q_len=5, kv_len=5)
    ours, _ = cpu_decode._decode_attention(module, q, k, v, None)
    ref, _ = sdpa_attention_forward(module, q, k, v, None)
    assert torch.equal(ours, ref)  # the very same call

    module, q, k, v = _inputs()
    per_head = torch.ones(q.shape[0], q.shape[1], 1, k.shape[2], dtype=torch.bool)
    ours, _ = cpu_decode._decode_attention(module, q, k, v, per_head)
    ref, _ = sdpa_attention_forward(module, q, k, v, per_head)
    assert torch.equal(ours, ref)


def test_register_is_idempotent_and_known_to_transformers():
    from transformers import AttentionInterface
    from transformers.masking_utils import ALL_MASK_ATTENTION_FUNCTIONS

    name = cpu_decode.register()
    assert cpu_decode.register() == name
    assert name in AttentionInterface().valid_keys()
    assert name in ALL_MASK_ATTENTION_FUNCTIONS.valid_keys()
