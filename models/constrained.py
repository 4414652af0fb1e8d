"""Per-row control of one batched `generate` call: JSON-schema constraints, sampling, seeds, limits.

transformers' `generate` takes one sampling configuration for the whole batch, but a micro-batch mixes
requests with different schemas, temperatures, seeds and max_tokens. So the hf backend runs `generate`
greedily and does everything per row in this logits processor:

- structured output: an llguidance matcher per row (the grammar engine vLLM also uses) masks the
  tokens that would break the row's JSON schema;
- sampling: rows with temperature > 0 draw their token here from their own seeded generator (top-p
  applied), and the processor leaves only that token open, so greedy picks it. A row's output then
  depends only on its own request and seed, not on what else shares the batch;
- max_tokens: a row that reached its own limit may only emit end-of-sequence.

`consume` and `control` also serve `models.hf_continuous`, which decodes without `generate`.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from models.base import BackendError

__all__ = ["GrammarCompiler", "RowControl", "RowsProcessor"]

# Compact JSON (no free whitespace): a weak model cannot stall by emitting blanks forever.
_JSON_OPTIONS = {"whitespace_flexible": False}


class GrammarCompiler:
    """Builds llguidance matchers for JSON schemas; the tokenizer wrap and grammars are cached."""

    def __init__(self, hf_tokenizer: Any, eos_ids: list[int]) -> None:
        import llguidance
        import llguidance.hf

        self._llguidance = llguidance
        self.tokenizer = llguidance.hf.from_tokenizer(hf_tokenizer, eos_token=eos_ids)
        self.vocab_size = self.tokenizer.vocab_size
        self._grammars: dict[str, str] = {}

    def matcher(self, schema: dict[str, Any]) -> Any:
        key = json.dumps(schema, sort_keys=True)
        grammar = self._grammars.get(key)
        if grammar is None:
            grammar = self._llguidance.LLMatcher.grammar_from_json_schema(schema, defaults=_JSON_OPTIONS)
            is_error, messages = self._llguidance.LLMatcher.validate_grammar_with_warnings(grammar, self.tokenizer)
            if is_error:
                raise ValueError(f"JSON schema not usable for constrained decoding: {messages[0]}")
            self._grammars[key] = grammar
        matcher = self._llguidance.LLMatcher(self.tokenizer, grammar, log_level=0)
        if matcher.is_error():
            raise ValueError(f"JSON schema not usable for constrained decoding: {matcher.get_error()}")
        return matcher


@dataclass
class RowControl:
    """What one output row of the batch must obey."""

    max_tokens: int
    temperature: float = 0.0
    top_p: float = 1.0
    seed: int | None = None
    matcher: Any = None
    generated: int = 0
    done: bool = False
    generator: torch.Generator | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.temperature > 0:
            self.generator = torch.Generator(device="cpu")
            if self.seed is None:
                self.generator.seed()
            else:
                self.generator.manual_seed(int(self.seed))


class RowsProcessor:
    """A transformers LogitsProcessor (duck-typed: `__call__(input_ids, scores) -> scores`)."""

    def __init__(self, rows: list[RowControl], eos_ids: list[int], prompt_len: int, grammar_vocab: int) -> None:
        self.rows = rows
        self.eos_ids = eos_ids
        self.prompt_len = prompt_len
        self.grammar_vocab = grammar_vocab

    def __call__(self, input_ids: torch.LongTensor, scores: torch.FloatTensor) -> torch.FloatTensor:
        step = input_ids.shape[1] - self.prompt_len
        for r, row in enumerate(self.rows):
            if row.done:
                continue
            if step > 0:
                self.consume(row, int(input_ids[r, -1]))
                if row.done:
                    continue
            self.control(row, scores[r])
        return scores

    def consume(self, row: RowControl, token: int) -> None:
        """Record the token a row just emitted (end-of-sequence marks the row done)."""
        if token in self.eos_ids:
            row.done = True
            return
        row.generated += 1
        if row.matcher is not None and not row.matcher.consume_token(token):
            raise BackendError(f"grammar rejected token {token}: {row.matcher.get_error()}")

    def control(self, row: RowControl, logits: torch.Tensor) -> None:
        """Mask (schema, limit) or sample this row's next-token logits in place."""
        if row.generated >= row.max_tokens:
            self._only(logits, self.eos_ids[0])
            return
        if row.matcher is not None:
            self._mask(row.matcher, logits)
        if row.temperature > 0:
            self._only(logits, self._sample(row, logits))

    def _mask(self, matcher: Any, logits: torch.Tensor) -> None:
        if matcher.is_error():
            raise BackendError(f"constrained decoding failed: {matcher.get_error()}")
        words = np.frombuffer(matcher.compute_bitmask(), dtype=np.uint8)
        allowed = np.unpackbits(words, bitorder="little")[: self.grammar_vocab].astype(bool)
        vocab = logits.shape[0]
        keep = torch.zeros(vocab, dtype=torch.bool)
        n = min(vocab, allowed.shape[0])
        keep[:n] = torch.from_numpy(allowed[:n])
        if not bool(keep.any()):
            raise BackendError("constrained decoding reached a state where no token is allowed")
        logits.masked_fill_(~keep.to(logits.device), float("-inf"))

    @staticmethod
    def _sample(row: RowControl, logits: torch.Tensor) -> int:
        probs = torch.softmax(logits.float().cpu() / row.temperature, dim=-1)
        if row.top_p < 1.0:
            sorted_p, order = torch.sort(probs, descending=True)
            cut = torch.cumsum(sorted_p, dim=-1) - sorted_p >= row.top_p
            sorted_p[cut] = 0.0
            probs = torch.zeros_like(probs).scatter_(0, order, sorted_p)
        return int(torch.multinomial(probs, 1, generator=row.generator))

    @staticmethod
    def _only(logits: torch.Tensor, token: int) -> None:
        logits.fill_(float("-inf"))
        logits[token] = 0.0
