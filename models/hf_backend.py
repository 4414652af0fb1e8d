"""`hf`: transformers on CPU or GPU, with real batching and JSON-schema-constrained decoding.

Concurrent `complete` calls (many streams of a run) are gathered by a micro-batcher: the first pending
request opens a short gather window (`gather_window_s`); rendering runs in a thread, and requests sent
together (e.g. by `asyncio.gather`) are always admitted together. A worker thread then serves them
one of two ways:

- continuous batching (default for text models with plain full-attention caches): one running
  batch, `models.hf_continuous.RunningBatch`. Before every decode step, pending requests join it (up
  to `max_batch_size` rows, one batched prefill); after every step, each finished row is answered at
  once and cut out of the cache. No stream waits for another's longer answer, and a request that
  arrives mid-generation starts at the next step.
- static batches (vision specs, caches that are not plain, or `continuous: false`): up to
  `max_batch_size` requests go through ONE left-padded `generate` call; requests that arrive while it
  runs form the next one.

Per-row schemas, sampling, seeds and max_tokens are handled by `models.constrained.RowsProcessor`
either way, so one batch may mix planner and judge calls.

A request with `n > 1` (BoN's N plans, SimuRA's policy and critic samples) takes n rows, row k seeded
`seed + k`. Continuous batching prefills its prompt ONCE and copies the resulting key/value rows and
first-token logits to its n rows (`RunningBatch.admit(rows=...)`), so n samples cost one prefill; the
static path still encodes the prompt n times (it serves vision specs, whose prompts are image-heavy).

System-prompt prefix cache: every agent role sends the same system message call after call (the
planner's holds the whole action list), so the backend keeps the key/value tensors of recent system
prefixes (LRU, `prefix_cache_entries`) and prefills only the rest of each prompt. A batch is laid out
per row as [cached prefix][pad][left-padded suffix]; the padding in the middle is masked and position
ids come from the attention mask, so each row sees exactly its own prompt. Text-only batches only
(image rows take the plain path), and only for models whose cache layers are plain full-attention
layers; `prefix_cache: false` turns it off.

Options (spec `options:` or keyword arguments): `device` ("cuda" if available, else "cpu"), `dtype`
(default: the spec's; on this 2-core CPU bf16 measured 1.5x faster than float32 at batch 1 and 2.2x
at batch 8 for SmolLM2, idle machine), `max_batch_size` (16), `gather_window_s` (0.02), `threads` (torch CPU threads),
`continuous` (true where possible, see above), `prefix_cache` (true), `prefix_cache_entries` (16),
`prefix_min_tokens` (32: shorter system prompts are not cached),
`fast_decode` (true on CPU for text specs with plain cache layers: `models.cpu_decode`, sdpa for
prefill and a grouped matmul per decode step, which cut a decode step of 8 rows x 1.1k cached tokens of
SmolLM2 bf16 from 208 ms to 73 ms here; torch's CPU flash kernel is slow with one query per row).
Vision specs (Qwen-VL family) take `{"type": "image", "image": PIL.Image}` content parts.
"""

from __future__ import annotations

import asyncio
import gc
import json
import threading
import time
from collections import OrderedDict
from collections.abc import Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from typing import Any

from models.base import BackendError, ChatRequest, ChatResult, ContextLengthError, Sampling
from models.specs import ModelSpec, set_offline_env

__all__ = ["HFBackend"]

_KNOWN_OPTIONS = {"device", "dtype", "max_batch_size", "gather_window_s", "threads", "model_path",
                  "prefix_cache", "prefix_cache_entries", "prefix_min_tokens", "fast_decode", "continuous"}


@dataclass
class _LoopQueue:
    """Requests waiting on one event loop, and how many more are being rendered right now."""

    pending: list[_Row] = field(default_factory=list)  # touched by the worker too: under `lock`
    lock: threading.Lock = field(default_factory=threading.Lock)
    preparing: int = 0
    arrived: asyncio.Event = field(default_factory=asyncio.Event)
    drainer: asyncio.Task[None] | None = None


@dataclass
class _Row:
    """One request, rendered and tokenized, waiting for its batch."""

    request: ChatRequest
    text: str
    prompt_tokens: int
    images: list[Any]
    ids: list[int]
    prefix_len: int  # leading tokens of `ids` that are the system message (0: nothing to cache)
    start: float
    future: asyncio.Future[ChatResult] = field(repr=False)
    outputs: dict[int, list[int]] = field(default_factory=dict, repr=False)  # continuous: finished rows

    @property
    def width(self) -> int:
        """Output rows this request takes in a batch."""
        return max(1, self.request.sampling.n)


def _as_image(image: Any) -> Any:
    """A PIL image as is; a path string is opened (the request contract allows PIL images only, but a
    path is what a user typing a request by hand would give)."""
    if isinstance(image, str):
        from PIL import Image

        try:
            return Image.open(image)
        except OSError as exc:
            raise BackendError(f"hf backend: cannot open image {image!r}: {exc}") from exc
    return image


class HFBackend:
    """A transformers model behind the `ChatBackend` protocol (see module docstring)."""

    name = "hf"

    def __init__(self, spec: ModelSpec, **options: Any) -> None:
        set_offline_env()
        unknown = set(options) - _KNOWN_OPTIONS
        if unknown:
            raise TypeError(f"hf backend: unknown options {sorted(unknown)}; known: {sorted(_KNOWN_OPTIONS)}")
        opts = {**{k: v for k, v in spec.options.items() if k in _KNOWN_OPTIONS}, **options}
        self.spec = spec
        self.model_id = spec.model_id
        self.context_length = spec.context_length
        self.max_batch_size = int(opts.get("max_batch_size", 16))
        self.gather_window_s = float(opts.get("gather_window_s", 0.02))
        self.generate_calls = 0  # one per batched `generate`; tests and `models check` read these
        self.batch_sizes: list[int] = []
        self.prefix_cache = bool(opts.get("prefix_cache", True))
        self.prefix_cache_entries = int(opts.get("prefix_cache_entries", 16))
        self.prefix_min_tokens = int(opts.get("prefix_min_tokens", 32))
        self.prefix_hits = 0  # rows whose system prefix came from the cache
        self.prefix_misses = 0  # prefixes computed
        self.prefilled_tokens = 0  # prompt tokens actually run through the model
        self.decode_steps = 0  # continuous batching: decode steps run, and rows summed over them
        self.decode_rows = 0
        self._closing = False
        self._prefix_kv: OrderedDict[tuple[int, ...], list[tuple[Any, Any]]] = OrderedDict()
        self._system_ids: OrderedDict[str, list[int]] = OrderedDict()
        self._system_lock = threading.Lock()
        self._queues: dict[asyncio.AbstractEventLoop, _LoopQueue] = {}
        self._executor = ThreadPoolExecutor(max_workers=1, thread_name_prefix="hf-generate")
        self._lock = threading.Lock()
        start = time.perf_counter()
        self._load(opts)
        self.load_s = time.perf_counter() - start

    # ---- loading -------------------------------------------------------------------------------

    def _load(self, opts: dict[str, Any]) -> None:
        from models.weights import materialize

        folder = opts.get("model_path") or materialize(self.spec)  # missing weights fail before heavy imports

        import torch
        from transformers import AutoModelForCausalLM, AutoModelForImageTextToText, AutoTokenizer

        from models.constrained import GrammarCompiler

        if opts.get("threads"):
            torch.set_num_threads(int(opts["threads"]))
        self.device = opts.get("device") or ("cuda" if torch.cuda.is_available() else "cpu")
        dtype_name = opts.get("dtype") or self.spec.dtype
        dtype = getattr(torch, dtype_name)
        self.tokenizer = AutoTokenizer.from_pretrained(folder)
        self.tokenizer.padding_side = "left"
        if self.tokenizer.pad_token_id is None:
            self.tokenizer.pad_token = self.tokenizer.eos_token
        self.image_processor = None
        if self.spec.vision:
            from models.tiny import image_processor_for

            self.model = AutoModelForImageTextToText.from_pretrained(folder, dtype=dtype)
            self.image_processor = image_processor_for(folder)
        else:
            self.model = AutoModelForCausalLM.from_pretrained(folder, dtype=dtype)
        self.model.to(self.device).eval()
        plain = not self.spec.vision and self._plain_cache_layers()
        self.prefix_cache = self.prefix_cache and plain
        self.fast_decode = bool(opts.get("fast_decode", self.device == "cpu")) and plain
        self.continuous = bool(opts.get("continuous", True)) and plain
        if self.fast_decode:
            from models import cpu_decode

            self.model.set_attn_implementation(cpu_decode.register())
        self.eos_ids = self._eos_ids()
        self.grammars = GrammarCompiler(self.tokenizer, self.eos_ids)

    def _plain_cache_layers(self) -> bool:
        """True when the model's KV cache is full attention in every layer (no sliding window, no
        linear-attention state), the only kind a stored prefix can be spliced into."""
        from transformers import DynamicCache
        from transformers.cache_utils import DynamicLayer

        try:
            cache = DynamicCache(config=self.model.config)
        except Exception:  # an architecture this cache class does not describe
            return False
        return all(type(layer) is DynamicLayer for layer in cache.layers)

    def _eos_ids(self) -> list[int]:
        ids: list[int] = []
        configured = self.model.generation_config.eos_token_id
        for value in [self.tokenizer.eos_token_id, *(configured if isinstance(configured, list) else [configured])]:
            if value is not None and value not in ids:
                ids.append(int(value))
        return ids

    # ---- rendering -----------------------------------------------------------------------------

    def _render(self, request: ChatRequest) -> tuple[str, list[Any]]:
        """Chat template applied; images collected in order and their placeholders expanded."""
        images: list[Any] = []
        messages = []
        for message in request.messages:
            content = message.get("content")
            if isinstance(content, list):
                for part in content:
                    if part.get("type") == "image":
                        images.append(_as_image(part["image"]))
                if not self.spec.vision:
                    if images:
                        raise BackendError(f"hf backend: {self.spec.address} is not a vision model; got an image")
                    content = "".join(p.get("text", "") for p in content)
                else:
                    content = [{"type": p["type"], **({"text": p["text"]} if p.get("type") == "text" else {})}
                               for p in content]
            messages.append({**message, "content": content if content is not None else ""})
        kwargs = {**self.spec.chat_template_kwargs, **(request.chat_template_kwargs or {})}
        text = self.tokenizer.apply_chat_template(messages, tokenize=False, add_generation_prompt=True, **kwargs)
        if images:
            text = self._expand_image_pads(text, images)
        return text, images

    def _expand_image_pads(self, text: str, images: list[Any]) -> str:
        """One `<|image_pad|>` per image becomes grid_t*grid_h*grid_w/merge^2 of them (Qwen-VL)."""
        assert self.image_processor is not None
        pad = "<|image_pad|>"
        if text.count(pad) != len(images):
            raise BackendError(f"hf backend: the chat template made {text.count(pad)} image slots for {len(images)} images")
        grids = self.image_processor([img.convert("RGB") for img in images], return_tensors="pt")["image_grid_thw"]
        merge = int(self.image_processor.merge_size) ** 2
        pieces = text.split(pad)
        out = pieces[0]
        for grid, rest in zip(grids.tolist(), pieces[1:], strict=True):
            out += "<|placeholder|>" * (grid[0] * grid[1] * grid[2] // merge) + rest
        return out.replace("<|placeholder|>", pad)

    def _system_prefix_len(self, request: ChatRequest, ids: list[int]) -> int:
        """How many leading tokens of `ids` are the rendered system message, when that is worth caching."""
        first = request.messages[0] if request.messages else {}
        if not self.prefix_cache or first.get("role") != "system" or not isinstance(first.get("content"), str):
            return 0
        kwargs = {**self.spec.chat_template_kwargs, **(request.chat_template_kwargs or {})}
        key = json.dumps([first["content"], kwargs], sort_keys=True, default=str)
        with self._system_lock:
            sys_ids = self._system_ids.get(key)
        if sys_ids is None:
            sys_text = self.tokenizer.apply_chat_template([first], tokenize=False, add_generation_prompt=False,
                                                          **kwargs)
            sys_ids = self.tokenizer(sys_text, add_special_tokens=False)["input_ids"]
            with self._system_lock:
                self._system_ids[key] = sys_ids
                while len(self._system_ids) > 256:
                    self._system_ids.popitem(last=False)
        n = len(sys_ids)
        # the prefix must tokenize identically inside the whole prompt, and leave at least one token to run
        if n < self.prefix_min_tokens or n >= len(ids) or ids[:n] != sys_ids:
            return 0
        return n

    def _prepare(self, index: int, request: ChatRequest) -> tuple[str, int, list[Any], list[int], int]:
        text, images = self._render(request)
        ids = self.tokenizer(text, add_special_tokens=False)["input_ids"]
        n_prompt = len(ids)
        needed = n_prompt + request.sampling.max_tokens
        if needed > self.context_length:
            raise ContextLengthError(
                f"hf backend ({self.spec.address}): request {index} needs {n_prompt} prompt + "
                f"{request.sampling.max_tokens} max_tokens = {needed} tokens > context length {self.context_length}"
            )
        if request.json_schema is not None:
            try:
                self.grammars.matcher(request.json_schema)
            except ValueError as exc:
                raise BackendError(f"hf backend ({self.spec.address}): request {index}: {exc}") from exc
        prefix_len = 0 if images else self._system_prefix_len(request, ids)
        return text, n_prompt, images, ids, prefix_len

    # ---- the ChatBackend protocol --------------------------------------------------------------

    async def complete(self, requests: Sequence[ChatRequest]) -> list[ChatResult]:
        """Render and check every request first (clear errors before any work), then batch them.

        Rendering runs in a thread; while any caller is still rendering, the batcher waits for it, so
        requests sent together (e.g. by `asyncio.gather`) always share one `generate` call.
        """
        if not requests:
            return []
        start = time.perf_counter()
        loop = asyncio.get_running_loop()
        for dead in [other for other in self._queues if other.is_closed()]:
            del self._queues[dead]  # left behind by an earlier asyncio.run
        queue = self._queues.setdefault(loop, _LoopQueue())
        queue.preparing += 1
        try:
            prepared = await asyncio.to_thread(lambda: [self._prepare(i, r) for i, r in enumerate(requests)])
        finally:
            queue.preparing -= 1
            queue.arrived.set()
        rows = [
            _Row(request=r, text=t, prompt_tokens=n, images=imgs, ids=ids, prefix_len=pl, start=start,
                 future=loop.create_future())
            for r, (t, n, imgs, ids, pl) in zip(requests, prepared, strict=True)
        ]
        with queue.lock:
            queue.pending.extend(rows)
        if queue.drainer is None or queue.drainer.done():
            queue.drainer = loop.create_task(self._drain(queue))
        return list(await asyncio.gather(*(row.future for row in rows)))

    async def _gather(self, queue: _LoopQueue) -> None:
        """The gather window, extended while callers that already started are still rendering."""
        if len(queue.pending) < self.max_batch_size:
            await asyncio.sleep(self.gather_window_s)
        while queue.preparing and len(queue.pending) < self.max_batch_size:
            queue.arrived.clear()
            await queue.arrived.wait()

    async def _drain(self, queue: _LoopQueue) -> None:
        """Serve this loop's queue until it is empty: continuously (one running batch that requests join
        and leave between decode steps) or in static batches, one `generate` call each."""
        loop = asyncio.get_running_loop()
        while queue.pending:
            await self._gather(queue)
            if self.continuous:
                await loop.run_in_executor(self._executor, self._serve, queue, loop)
                continue
            with queue.lock:
                batch, queue.pending[:] = queue.pending[: self.max_batch_size], queue.pending[self.max_batch_size :]
            try:
                outputs = await loop.run_in_executor(self._executor, self._generate, batch)
            except Exception as exc:  # the whole batch failed: every caller hears why
                error = exc if isinstance(exc, BackendError) else BackendError(f"hf backend: generate failed: {exc!r}")
                for row in batch:
                    if not row.future.done():
                        row.future.set_exception(error)
                continue
            now = time.perf_counter()
            for row, (texts, n_completion) in zip(batch, outputs, strict=True):
                if not row.future.done():
                    row.future.set_result(ChatResult(
                        texts=texts, prompt_tokens=row.prompt_tokens, completion_tokens=n_completion,
                        latency_s=now - row.start, model=self.model_id,
                    ))

    # ---- continuous batching (worker thread) ----------------------------------------------------

    def _serve(self, queue: _LoopQueue, loop: asyncio.AbstractEventLoop) -> None:
        """Run one `RunningBatch` until nothing is pending or running: before each decode step, admit
        pending requests up to `max_batch_size` rows (one batched prefill); after it, answer every
        request whose rows all finished. A model error fails the rows it touched, not the queue."""
        import torch

        from models.hf_continuous import RunningBatch

        running = RunningBatch(self.model, self.eos_ids, self.grammars.vocab_size)
        with self._lock, torch.inference_mode():
            try:
                while not self._closing:
                    admitted = self._take(queue, self.max_batch_size - len(running), first=not running.slots)
                    if admitted:
                        self._admit(running, admitted, loop)
                    running.drop([s for s in running.slots if s.owner.future.done()])  # callers gone
                    if not running.slots:
                        if not admitted:
                            break
                        continue
                    self.decode_steps += 1
                    self.decode_rows += len(running)
                    try:
                        finished = running.step()
                    except Exception as exc:
                        finished = running.fail_all(exc)
                    self._finish(finished, loop)
            except Exception as exc:  # a bug here must not leave callers waiting, nor stop the queue
                self._finish(running.fail_all(BackendError(f"hf backend: batching failed: {exc!r}")), loop)
            finally:
                if running.slots:  # closing: nobody will step these again
                    self._finish(running.fail_all(BackendError("hf backend closed")), loop)

    def _take(self, queue: _LoopQueue, room: int, *, first: bool) -> list[_Row]:
        """Pending requests whose rows fit in `room` (an empty batch takes at least one), in order."""
        taken: list[_Row] = []
        with queue.lock:
            while queue.pending and (queue.pending[0].width <= room or (first and not taken)):
                row = queue.pending.pop(0)
                room -= row.width
                taken.append(row)
        return taken

    def _admit(self, running: Any, admitted: list[_Row], loop: asyncio.AbstractEventLoop) -> None:
        from models.constrained import RowControl
        from models.hf_continuous import Slot

        self.generate_calls += 1
        self.batch_sizes.append(sum(row.width for row in admitted))
        # On a CPU a prefill is compute-bound from one row on, so a batched prefill gains nothing and
        # pays for padding every prompt to the longest (a 130-token judge prompt beside an 800-token
        # planner one costs 1,600 token-passes instead of 930): there each request prefills alone.
        groups = [admitted] if self.device != "cpu" else [[row] for row in admitted]
        for group in groups:
            slots = [Slot(owner=row, index=k, control=RowControl(row.request.sampling.max_tokens))
                     for row in group for k in range(row.width)]
            try:
                for slot in slots:
                    s: Sampling = slot.owner.request.sampling
                    schema = slot.owner.request.json_schema
                    slot.control = RowControl(s.max_tokens, s.temperature, s.top_p,
                                              None if s.seed is None else s.seed + slot.index,
                                              self.grammars.matcher(schema) if schema else None)
                # one prefill row per request: its n slots share it (`RunningBatch.admit` copies it)
                input_ids, mask, cache = self._prefill_inputs(group)
                prompt_row = {id(row): i for i, row in enumerate(group)}
                finished = running.admit(slots, input_ids, mask, cache, [prompt_row[id(s.owner)] for s in slots])
            except Exception as exc:
                for slot in slots:
                    slot.error = exc
                finished = slots
            self._finish(finished, loop)

    def _finish(self, slots: list[Any], loop: asyncio.AbstractEventLoop) -> None:
        """Record finished rows; a request whose rows are all in (or one failed) gets its answer."""
        now = time.perf_counter()
        for slot in slots:
            row: _Row = slot.owner
            if slot.error is not None:
                error = slot.error if isinstance(slot.error, BackendError) else \
                    BackendError(f"hf backend: generation failed: {slot.error!r}")
                loop.call_soon_threadsafe(_settle, row.future, None, error)
                continue
            row.outputs[slot.index] = slot.tokens
            if len(row.outputs) == row.width:
                outs = [row.outputs[k] for k in range(row.width)]
                result = ChatResult(
                    texts=[self.tokenizer.decode(ids, skip_special_tokens=True) for ids in outs],
                    prompt_tokens=row.prompt_tokens, completion_tokens=sum(len(ids) for ids in outs),
                    latency_s=now - row.start, model=self.model_id,
                )
                loop.call_soon_threadsafe(_settle, row.future, result, None)

    # ---- static batches ------------------------------------------------------------------------

    def _generate(self, batch: list[_Row]) -> list[tuple[list[str], int]]:
        """Run ONE `generate` over every output row of the batch (n rows per request)."""
        import torch
        from transformers import GenerationConfig, LogitsProcessorList

        from models.constrained import RowControl, RowsProcessor

        texts: list[str] = []
        images: list[Any] = []
        controls: list[RowControl] = []
        rows: list[_Row] = []
        for row in batch:
            s: Sampling = row.request.sampling
            for k in range(max(1, s.n)):
                texts.append(row.text)
                images.extend(row.images)
                rows.append(row)
                seed = None if s.seed is None else s.seed + k
                matcher = self.grammars.matcher(row.request.json_schema) if row.request.json_schema else None
                controls.append(RowControl(s.max_tokens, s.temperature, s.top_p, seed, matcher))
        use_prefix = self.prefix_cache and not images and any(r.prefix_len for r in rows)
        max_new = max(c.max_tokens for c in controls) + 1
        with self._lock, torch.inference_mode():
            if use_prefix:
                inputs = self._encode_with_prefixes(rows)
            else:
                inputs = self._encode(texts, images)
                self.prefilled_tokens += sum(len(r.ids) for r in rows)
            prompt_len = inputs["input_ids"].shape[1]
            processor = RowsProcessor(controls, self.eos_ids, prompt_len, self.grammars.vocab_size)
            config = GenerationConfig(
                max_new_tokens=max_new, do_sample=False,
                eos_token_id=self.eos_ids, pad_token_id=self.tokenizer.pad_token_id,
            )
            self.generate_calls += 1
            self.batch_sizes.append(len(controls))
            out = self.model.generate(**inputs, generation_config=config,
                                      logits_processor=LogitsProcessorList([processor]))
        return self._decode(batch, out[:, prompt_len:].cpu(), controls)

    def _prefix_tensors(self, ids: list[int]) -> list[tuple[Any, Any]]:
        """Per-layer (keys, values) of a system prefix, [1, heads, len, dim]; computed once, then LRU."""
        import torch

        key = tuple(ids)
        hit = self._prefix_kv.get(key)
        if hit is not None:
            self._prefix_kv.move_to_end(key)
            self.prefix_hits += 1
            return hit
        self.prefix_misses += 1
        self.prefilled_tokens += len(ids)
        out = self.model(input_ids=torch.tensor([ids], device=self.device), use_cache=True)
        tensors = [(layer.keys, layer.values) for layer in out.past_key_values.layers]
        self._prefix_kv[key] = tensors
        while len(self._prefix_kv) > self.prefix_cache_entries:
            self._prefix_kv.popitem(last=False)
        return tensors

    def _encode_with_prefixes(self, rows: list[_Row]) -> dict[str, Any]:
        """Inputs for `generate` with each row's cached system prefix spliced into `past_key_values`."""
        import torch

        suffix_ids, mask, cache = self._prefill_inputs(rows)
        width_p = max(r.prefix_len for r in rows)  # `generate` wants the cached columns' ids in front
        front = torch.tensor([r.ids[: r.prefix_len] + [int(self.tokenizer.pad_token_id)] * (width_p - r.prefix_len)
                              for r in rows], dtype=suffix_ids.dtype, device=suffix_ids.device)
        return {"input_ids": torch.cat([front, suffix_ids], dim=1), "attention_mask": mask, "past_key_values": cache}

    def _prefill_inputs(self, rows: list[_Row]) -> tuple[Any, Any, Any]:
        """(input ids, attention mask, cache) for prefilling `rows`, cached system prefixes spliced in.

        Row i is laid out as [prefix_i][pad up to the longest prefix][pad][suffix_i]: the stored prefix
        fills the first columns of the cache, everything else in the cache is masked, and the model
        only runs the columns after the cache (all of a row's tokens when nothing is cached: the cache
        is then empty). Position ids (mask cumsum) continue each row's prefix.
        """
        import torch
        from transformers import DynamicCache

        pad = int(self.tokenizer.pad_token_id)
        width_p = max(r.prefix_len for r in rows)
        width_s = max(len(r.ids) - r.prefix_len for r in rows)
        input_ids, mask = [], []
        for r in rows:
            p, suffix = r.prefix_len, r.ids[r.prefix_len:]
            input_ids.append([pad] * (width_s - len(suffix)) + suffix)
            mask.append([1] * p + [0] * (width_p - p) + [0] * (width_s - len(suffix)) + [1] * len(suffix))
            self.prefilled_tokens += len(suffix)
        if not width_p:
            return (torch.tensor(input_ids, device=self.device), torch.tensor(mask, device=self.device),
                    DynamicCache(config=self.model.config))
        per_row = [self._prefix_tensors(r.ids[: r.prefix_len]) if r.prefix_len else None for r in rows]
        template = next(t for t in per_row if t is not None)
        layers = []
        for layer_index, (k0, v0) in enumerate(template):
            keys = k0.new_zeros((len(rows), k0.shape[1], width_p, k0.shape[3]))
            values = v0.new_zeros((len(rows), v0.shape[1], width_p, v0.shape[3]))
            for i, tensors in enumerate(per_row):
                if tensors is not None:
                    k, v = tensors[layer_index]
                    keys[i, :, : k.shape[2]] = k[0]
                    values[i, :, : v.shape[2]] = v[0]
            layers.append((keys, values))
        return (torch.tensor(input_ids, device=self.device), torch.tensor(mask, device=self.device),
                DynamicCache(ddp_cache_data=layers, config=self.model.config))

    def _encode(self, texts: list[str], images: list[Any]) -> dict[str, Any]:
        inputs = dict(self.tokenizer(texts, return_tensors="pt", padding=True, add_special_tokens=False))
        if images:
            assert self.image_processor is not None
            vision = self.image_processor([img.convert("RGB") for img in images], return_tensors="pt")
            inputs["pixel_values"] = vision["pixel_values"].to(self.model.dtype)
            inputs["image_grid_thw"] = vision["image_grid_thw"]
        return {k: v.to(self.device) for k, v in inputs.items()}

    def _decode(self, batch: list[_Row], generated: Any, controls: list[Any]) -> list[tuple[list[str], int]]:
        results: list[tuple[list[str], int]] = []
        i = 0
        for row in batch:
            outs, total = [], 0
            for _ in range(max(1, row.request.sampling.n)):
                ids = [int(t) for t in generated[i]]
                cut = next((j for j, t in enumerate(ids) if t in self.eos_ids), len(ids))
                ids = ids[: min(cut, controls[i].max_tokens)]
                total += len(ids)
                outs.append(self.tokenizer.decode(ids, skip_special_tokens=True))
                i += 1
            results.append((outs, total))
        return results

    async def aclose(self) -> None:
        """Stop batching and free the model (GPU memory included)."""
        for queue in self._queues.values():
            if queue.drainer is not None:
                queue.drainer.cancel()
        self._queues.clear()
        self._closing = True  # a running continuous batch stops at its next step
        self._executor.shutdown(wait=True)
        self._prefix_kv.clear()
        self.model = None
        gc.collect()
        try:
            import torch

            if torch.cuda.is_available():
                torch.cuda.empty_cache()
        except ImportError:
            pass


def _settle(future: asyncio.Future[ChatResult], result: ChatResult | None, error: BaseException | None) -> None:
    """Complete a caller's future on its own loop (scheduled there from the worker thread)."""
    if future.done():
        return
    if error is not None:
        future.set_exception(error)
    else:
        future.set_result(result)
