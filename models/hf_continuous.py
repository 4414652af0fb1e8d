"""Continuous batching for the hf backend: rows join and leave one running decode batch between steps.

A static batch (one `generate` call) runs until its LONGEST row is done: a stream whose short judge
answer finished at step 20 waits for a planner row still at step 120, and a request that arrives
meanwhile waits for the whole batch. `RunningBatch` keeps the batch's key/value cache
([rows, heads, length, dim] per layer) and its 2-D attention mask between decode steps, so the
backend's worker can, before every step, prefill whatever request is pending and splice it in, and,
after every step, hand back each row that finished and cut it out of the cache.

Layout: a new row is left-padded to the running length (or the running rows to the new one) and the
padding is masked; position ids count each row's own tokens. So every row attends to exactly its own
prompt and output, whatever else shares the batch: in float32 a row decodes the same tokens alone,
in a static batch, or joining a running one (bf16 kernels may round differently with the batch size).
Leading columns that no remaining row uses are trimmed when rows leave.

Per-row schema masks, sampling, seeds and max_tokens come from `models.constrained.RowsProcessor`.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import torch
import torch.nn.functional as F

from models.base import BackendError
from models.constrained import RowControl, RowsProcessor

try:  # the cache layer protocol; importing this module must not need transformers
    from transformers.cache_utils import DynamicLayer
except ImportError:  # pragma: no cover - transformers is a dependency of the hf backend
    DynamicLayer = object  # type: ignore[assignment,misc]

__all__ = ["BufferLayer", "RunningBatch", "Slot"]


@dataclass(eq=False)
class Slot:
    """One output row in the running batch (a request with n > 1 has n slots)."""

    owner: Any  # what the caller needs to route the result (the backend's pending request)
    index: int  # which of the owner's outputs this row is
    control: RowControl
    tokens: list[int] = field(default_factory=list)  # emitted so far, end-of-sequence excluded
    next_token: int = -1  # emitted but not yet run through the model
    position: int = 0  # position id of `next_token`: this row's own token count before it
    error: BaseException | None = None

    @property
    def done(self) -> bool:
        return self.control.done or self.error is not None


class RunningBatch:
    """The running decode batch of one worker thread (not thread-safe; call under the model's lock)."""

    def __init__(self, model: Any, eos_ids: list[int], grammar_vocab: int) -> None:
        self.model = model
        self.rules = RowsProcessor([], eos_ids, 0, grammar_vocab)
        self.slots: list[Slot] = []
        self.cache: Any = None  # transformers DynamicCache of the running rows
        self.mask: torch.Tensor | None = None  # [rows, length], 1 where a row has a token

    def __len__(self) -> int:
        return len(self.slots)

    @property
    def length(self) -> int:
        return 0 if self.mask is None else int(self.mask.shape[1])

    def admit(self, slots: list[Slot], input_ids: torch.Tensor, mask: torch.Tensor, cache: Any,
              rows: list[int] | None = None) -> list[Slot]:
        """Prefill new rows and splice them in; returns the rows already finished by their first token.

        `cache` holds what precedes `input_ids` for these rows (spliced system prefixes, or nothing);
        `mask` covers cache and input columns together, [prompts, cache length + input length].
        `rows[i]` is the prompt row slot i decodes from (default: row i). A request with n > 1 sends its
        prompt ONCE: the prefill runs per prompt, and its key/value rows and last logits are then
        copied to each of its n slots (one prefill instead of n; each slot samples with its own seed).
        """
        width = int(input_ids.shape[1])
        past = int(mask.shape[1]) - width
        position_ids = (mask.cumsum(-1) - 1).clamp(min=0)[:, past:]
        out = self.model(input_ids=input_ids, attention_mask=mask, position_ids=position_ids,
                         past_key_values=cache, use_cache=True, logits_to_keep=1,
                         cache_position=torch.arange(past, past + width, device=input_ids.device))
        new_cache, logits = out.past_key_values, out.logits[:, -1, :]
        if rows is not None and rows != list(range(int(input_ids.shape[0]))):
            index = torch.tensor(rows, device=input_ids.device)
            new_cache.layers = [_plain(k.index_select(0, index), v.index_select(0, index))
                                for k, v in map(_written, new_cache.layers)]
            mask, logits = mask.index_select(0, index), logits.index_select(0, index)
        for i, slot in enumerate(slots):
            slot.position = int(mask[i].sum())
        first = len(self.slots)
        self._splice(slots, new_cache, mask)
        finished = self._emit(logits, self.slots[first:])
        self._drop(finished)
        self._own_cache()
        return finished

    def step(self) -> list[Slot]:
        """One decode step for every running row; returns (and drops) the rows that finished."""
        assert self.mask is not None and self.slots
        device = self.mask.device
        rows = len(self.slots)
        input_ids = torch.tensor([[s.next_token] for s in self.slots], device=device)
        position_ids = torch.tensor([[s.position] for s in self.slots], device=device)
        past = self.length
        if any(getattr(layer, "room", 1) < 1 for layer in self.cache.layers):  # a row outlived its max_tokens
            self._own_cache()
        self.mask = torch.cat([self.mask, self.mask.new_ones((rows, 1))], dim=1)
        out = self.model(input_ids=input_ids, attention_mask=self.mask, position_ids=position_ids,
                         past_key_values=self.cache, use_cache=True,
                         cache_position=torch.tensor([past], device=device))
        for slot in self.slots:
            slot.position += 1
        finished = self._emit(out.logits[:, -1, :], self.slots)
        if finished:
            self._drop(finished)
            self._own_cache()
        return finished

    def drop(self, slots: Iterable[Slot]) -> None:
        """Cut rows out of the batch (a caller gave up on them)."""
        gone = [s for s in slots if s in self.slots]
        if gone:
            self._drop(gone)
            self._own_cache()

    def fail_all(self, error: BaseException) -> list[Slot]:
        """Every running row failed (the model raised): they are returned and the batch is empty."""
        failed = self.slots
        for slot in failed:
            slot.error = error
        self.slots, self.cache, self.mask = [], None, None
        return failed

    # ---- internals ------------------------------------------------------------------------------

    def _emit(self, logits: torch.Tensor, slots: list[Slot]) -> list[Slot]:
        """Pick each row's next token from its logits row (schema, sampling, limit); the finished rows."""
        finished = []
        for i, slot in enumerate(slots):
            row = slot.control
            try:
                scores = logits[i].float()  # masked in place; these logits are not used again
                self.rules.control(row, scores)
                token = int(torch.argmax(scores))
                self.rules.consume(row, token)
            except BackendError as exc:  # this row's grammar failed; the others go on
                slot.error = exc
                finished.append(slot)
                continue
            if row.done:
                finished.append(slot)
                continue
            slot.tokens.append(token)
            slot.next_token = token
            if row.generated >= row.max_tokens:
                row.done = True
                finished.append(slot)
        return finished

    def _splice(self, slots: list[Slot], cache: Any, mask: torch.Tensor) -> None:
        """Append new rows (their cache and mask) to the running ones, left-padding to one length."""
        if self.cache is None:
            self.slots, self.cache, self.mask = list(slots), cache, mask
            return
        assert self.mask is not None
        width = max(self.length, int(mask.shape[1]))
        layers = []
        for mine, theirs in zip(self.cache.layers, cache.layers, strict=True):
            (k0, v0), (k1, v1) = _written(mine), _written(theirs)
            layers.append((torch.cat([_pad_left(k0, width), _pad_left(k1, width)], dim=0),
                           torch.cat([_pad_left(v0, width), _pad_left(v1, width)], dim=0)))
        self.cache.layers = [_plain(k, v) for k, v in layers]
        self.mask = torch.cat([F.pad(self.mask, (width - self.length, 0)), F.pad(mask, (width - mask.shape[1], 0))])
        self.slots.extend(slots)

    def _drop(self, gone: list[Slot]) -> None:
        if not gone:
            return
        keep = [i for i, s in enumerate(self.slots) if s not in gone]
        if not keep:
            self.slots, self.cache, self.mask = [], None, None
            return
        assert self.mask is not None
        index = torch.tensor(keep, device=self.mask.device)
        mask = self.mask.index_select(0, index)
        used = torch.nonzero(mask.any(dim=0))
        start = int(used[0]) if used.numel() else 0  # leading columns only the dropped rows used
        self.mask = mask[:, start:]
        self.cache.layers = [_plain(k.index_select(0, index)[:, :, start:], v.index_select(0, index)[:, :, start:])
                             for k, v in map(_written, self.cache.layers)]
        self.slots = [self.slots[i] for i in keep]

    def _own_cache(self) -> None:
        """Move the cache into `BufferLayer`s with room for the running rows' remaining tokens, so a
        decode step writes its column in place. Runs after the batch's rows change."""
        if self.cache is None or not self.slots:
            return
        room = max(1, max(s.control.max_tokens - s.control.generated for s in self.slots) + 1)
        self.cache.layers = [BufferLayer(*_written(layer), room) for layer in self.cache.layers]


class BufferLayer(DynamicLayer):  # type: ignore[misc,valid-type]
    """A full-attention cache layer in a preallocated buffer [rows, heads, length + room, dim].

    transformers' `DynamicLayer` appends each step's key/value column with `torch.cat`, copying the
    whole cache every step: at 8 rows x 1,200 cached tokens that copy was a third of a SmolLM2 decode
    step on this CPU. Here a step writes its column in place. Attention gets the WHOLE buffer (the
    unwritten columns are zeros, and `get_mask_sizes` makes the attention mask that wide, so they are
    masked out, as with transformers' static cache): a view of the written part would be strided, and
    CPU batched matmuls copy strided operands, which costs as much as the copy this layer avoids.
    """

    def __init__(self, keys: torch.Tensor, values: torch.Tensor, room: int) -> None:
        super().__init__()
        self.dtype, self.device = keys.dtype, keys.device
        self.is_initialized = True
        rows, heads, length, _ = keys.shape
        self.keys = keys.new_zeros((rows, heads, length + room, keys.shape[3]))
        self.values = values.new_zeros((rows, heads, length + room, values.shape[3]))
        self.keys[:, :, :length] = keys
        self.values[:, :, :length] = values
        self.length = length

    @property
    def room(self) -> int:
        return int(self.keys.shape[2]) - self.length

    def update(self, key_states: torch.Tensor, value_states: torch.Tensor, *args: Any,
               **kwargs: Any) -> tuple[torch.Tensor, torch.Tensor]:
        width = int(key_states.shape[-2])
        if width > self.room:  # the mask was already sized from this buffer: it cannot grow here
            raise RuntimeError(f"cache buffer full ({self.length} + {width} > {self.keys.shape[2]})")
        self.keys[:, :, self.length:self.length + width] = key_states
        self.values[:, :, self.length:self.length + width] = value_states
        self.length += width
        return self.keys, self.values

    def get_mask_sizes(self, query_length: int) -> tuple[int, int]:
        return int(self.keys.shape[2]), 0

    def get_seq_length(self) -> int:
        return self.length


def _plain(keys: torch.Tensor, values: torch.Tensor) -> Any:
    """A transformers `DynamicLayer` holding these keys and values (`_own_cache` then buffers it)."""
    layer = DynamicLayer()
    layer.lazy_initialization(keys, values)
    layer.keys, layer.values = keys, values
    return layer


def _written(layer: Any) -> tuple[torch.Tensor, torch.Tensor]:
    """A cache layer's written keys and values, [rows, heads, length, dim]."""
    if isinstance(layer, BufferLayer):
        return layer.keys[:, :, :layer.length], layer.values[:, :, :layer.length]
    return layer.keys, layer.values


def _pad_left(tensor: torch.Tensor, width: int) -> torch.Tensor:
    """[rows, heads, length, dim] zero-padded on the left of the length axis to `width`."""
    extra = width - tensor.shape[2]
    return tensor if extra == 0 else F.pad(tensor, (0, 0, extra, 0))
