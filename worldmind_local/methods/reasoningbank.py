"""ReasoningBank (baselines.md §7) on ReAct's planner.

- Read (`start`, once per episode, the instruction as the query): cosine between the instruction's
  all-MiniLM-L6-v2 embedding and the stored instructions (C7, instead of gemini-embedding-001); the
  top 1 past task (`top_k`, §7(4) `select_memory(n=1)`) among the tasks that have items (§7(6)
  [decision]), the same normalised instruction skipped (C4); ALL its items are injected after the system
  block and examples, before the instruction line (`react_messages(extra_system=...)`), under the
  reference's header adapted: memory items from past interactions, use them when relevant, and say in
  `reasoning_and_reflection` for each item whether it is used (§7(5)).
- [decision] The reference's query-side instruction prefix ("Instruct: given prior queries ...") is
  dropped: it is a gemini-embedding convention; MiniLM is not instruction-tuned (§7(5) allows this
  when logged; here it is logged in this docstring and the README table).
- Write (`finish`): the success signal (`llm_judge` by default, C5) labels the episode; then one
  extraction call (the `extractor` role, the backbone; T=1.0, §7(4)) with the success prompt or the
  failure prompt, given "**Query:**", the C6 trajectory and "The task succeeded/failed because: <the
  judge's thoughts>". At most 3 items (title, description, content) become `memory_item` entries (for
  successes AND failures), `success` set to the label. No deduplication, no consolidation (§7(2)).
- [decision] The extractor answers JSON (`{reasoning, memory_items: [...]}`, schema-constrained, as
  every structured call of this project); a non-JSON answer is parsed by its "# Memory Item" headers
  (§7(6)), never by blank lines. An answer with no item stores nothing (counted in the stats).
- Calls: 1 per planning step; per episode +1 memory judge (`llm_judge`; T=0) and +1 extraction.
"""

from __future__ import annotations

import re
from typing import Any, ClassVar

from pydantic import Field

from worldmind_local.agent.driver import Episode
from worldmind_local.agent.plan import PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import load_template, render
from worldmind_local.methods.base import MethodConfig, Proposal
from worldmind_local.methods.memory_common import (
    MemoryConfig,
    MemoryStats,
    StoreMethod,
    SuccessSignal,
    backbone_calls,
    decide_success,
    embed_query,
    finish_stats,
    new_entry,
    note_retrieved,
    remember_answer,
    render_trajectory,
)
from worldmind_local.methods.react import ask_planner, eb_examples, react_messages

__all__ = ["ReasoningBank", "ReasoningBankConfig", "ReasoningBankStats", "parse_items", "format_items",
           "EXTRACTION_SCHEMA"]

KIND = "memory_item"
DEFAULT_TOP_K = 1  # run.py select_memory(n=1)
MAX_ITEMS = 3
_LIMITS = {"title": 120, "description": 300, "content": 800}

EXTRACTION_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "reasoning": {"type": "string", "maxLength": 1500},
        "memory_items": {
            "type": "array", "maxItems": MAX_ITEMS,
            "items": {
                "type": "object",
                "properties": {k: {"type": "string", "maxLength": n} for k, n in _LIMITS.items()},
                "required": list(_LIMITS), "additionalProperties": False,
            },
        },
    },
    "required": ["reasoning", "memory_items"],
    "additionalProperties": False,
}


class ReasoningBankConfig(MemoryConfig):
    success_signal: SuccessSignal = Field(
        "llm_judge", description="what decides a memory write: env success or an LLM judge of the trajectory")
    top_k: int | None = Field(None, ge=0, le=50, description="past tasks whose items are retrieved per episode "
                                                           "(default 1)")
    extraction_temperature: float = Field(1.0, ge=0.0, le=2.0,
                                          description="ReasoningBank extraction temperature (reference 1.0)")
    extraction_max_tokens: int = Field(1024, ge=16, le=32768, description="ReasoningBank extraction output tokens")


class ReasoningBankStats(MemoryStats):
    items_shown: int = 0
    extractions: int = 0
    items_extracted: int = 0
    extraction_unparseable: int = 0


def _clean(value: Any, limit: int) -> str:
    return " ".join(str(value or "").split())[:limit]


_HEADER = re.compile(r"^#\s*Memory Item\b.*$", re.IGNORECASE | re.MULTILINE)
_FIELD = re.compile(r"^##\s*(Title|Description|Content)\b[:\s]*(.*?)(?=^##\s|\Z)", re.IGNORECASE | re.MULTILINE | re.DOTALL)


def parse_items(text: str) -> list[tuple[str, str, str]]:
    """At most 3 (title, description, content) items, from the JSON answer or "# Memory Item" blocks;
    an item without content is dropped."""
    raw: list[dict[str, Any]] = []
    try:
        items = extract_first_json_object(text).get("memory_items")
        raw = [i for i in items if isinstance(i, dict)] if isinstance(items, list) else []
    except PlanParseError:
        for block in _HEADER.split(text)[1:]:
            raw.append({m.group(1).lower(): m.group(2) for m in _FIELD.finditer(block)})
    out = []
    for item in raw:
        fields = tuple(_clean(item.get(k), n) for k, n in _LIMITS.items())
        if fields[2]:
            out.append(fields)
    return out[:MAX_ITEMS]


def format_items(entries: list[Any]) -> str:
    blocks = [render(load_template("common", "reasoningbank_item"), number=i, title=e.title or "",
                     description=e.description or "", content=e.text) for i, e in enumerate(entries, 1)]
    return render(load_template("common", "reasoningbank_block"), items="\n\n".join(blocks))


class ReasoningBank(StoreMethod):
    name: ClassVar[str] = "reasoningbank"
    description: ClassVar[str] = ("ReasoningBank: <=3 reasoning items per episode from judged successes and "
                                  "failures; the top-1 past task's items in ReAct's prompt")
    config_class: ClassVar[type[MethodConfig]] = ReasoningBankConfig
    config: ReasoningBankConfig



    async def start(self, ep: Episode) -> None:
        stats = ReasoningBankStats(success_signal=self.config.success_signal)
        examples = eb_examples(ep, self.config.n_shots)
        stats.examples = examples.count("## Example ")
        ep.state.update(stats=stats, examples=examples, block="", retrieved=[])
        k = self.config.top_k if self.config.top_k is not None else DEFAULT_TOP_K
        if ep.ctx.memory is None or k <= 0:
            return
        query = await embed_query(ep, ep.task.instruction)
        groups = ep.ctx.memory.retrieve_groups(query, k, kind=KIND,
                                               exclude_instruction=ep.task.instruction)
        items = [e for group in groups for e in group]
        if items:
            ep.state.update(block=format_items(items), retrieved=note_retrieved(ep, items, stats))
            stats.items_shown = len(items)

    async def plan(self, ep: Episode) -> Proposal:
        index = len(ep.record.plans)
        messages = react_messages(ep, examples=ep.state["examples"], extra_system=ep.state["block"],
                                  max_plan_actions=self.config.max_plan_actions)
        extra = {"retrieved": ep.state["retrieved"]} if ep.state["retrieved"] else {}
        proposal = await ask_planner(ep, messages, self.config, call_key=f"planner:{index}", extra=extra)
        remember_answer(ep, index, proposal.raw)
        return proposal

    async def finish(self, ep: Episode) -> None:
        stats: ReasoningBankStats = ep.state["stats"]
        try:
            if ep.ctx.memory is None:
                return
            success, thoughts = await decide_success(ep, self.config, stats)
            for title, description, content in await self._extract(ep, success, thoughts, stats):
                ep.experience.append(new_entry(ep, KIND, content, success=success, signal=self.config.success_signal,
                                               title=title, description=description))
        finally:
            finish_stats(ep, stats)

    async def _extract(self, ep: Episode, success: bool, thoughts: str,
                       stats: ReasoningBankStats) -> list[tuple[str, str, str]]:
        cfg, word = self.config, "succeeded" if success else "failed"
        outcome = f"The task {word} because: {thoughts}" if thoughts else f"The task {word}."
        system = load_template("common", "reasoningbank_extract_success" if success else "reasoningbank_extract_failure")
        user = render(load_template("common", "reasoningbank_extract_user"), instruction=ep.task.instruction.strip(),
                      trajectory=render_trajectory(ep), outcome=outcome)
        calls = backbone_calls(ep)
        request = calls.request("extractor", [{"role": "system", "content": system.strip()},
                                              {"role": "user", "content": user}],
                                call_key="extractor", max_tokens=cfg.extraction_max_tokens,
                                json_schema=EXTRACTION_SCHEMA, temperature=cfg.extraction_temperature)
        result = await calls.ask(request, call_key="extractor")
        items = parse_items(result.text)
        stats.extractions += 1
        stats.items_extracted += len(items)
        stats.extraction_unparseable += int(not items)
        return items
