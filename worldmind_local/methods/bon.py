"""BoN (Best-of-N), step-level: N sampled ReAct plans per planning step, one LLM selector picks one
(baselines.md §3, default variant: no env reset, no peeking at the env's future, no ground truth).

Per planning step:
1. the exact ReAct prompt (§2, `react.react_messages`), asked ONCE with `n=N` at `sample_temperature`
   (seeded: every backend seeds row k of a request with seed + k, so a run repeats);
2. each of the N texts parsed with the shared robust parser (C3); a candidate is dropped when it is
   unparseable, has an out-of-range FIRST id, or is empty (see [decision] below);
3. survivors with identical executable id sequences are merged, keeping a count and their first sample;
4. one distinct candidate: used without a selector call (§3 step 5);
5. otherwise ONE selector request at T=0 (`selector_temperature`) that sees what the planner sees
   (rules, action list, instruction, the image or text the driver allows, the history with feedback)
   plus the numbered distinct candidates (language plan and action names), never `info`
   (success/progress); it answers `{analysis, best_index}`;
6. the chosen candidate's plan goes back to the driver, which runs it under EB's protocol (C1).

Calls per planning step: 1 request (N generations) when the candidates agree, else 2 requests
(N + 1 generations). Every candidate, the merge and the selector's answer are in `Proposal.extra["bon"]`
(the step's PlanRecord).

[decision] Deterministic fallback (§3): when the selector's answer is unparseable or its index is out
of range, take the highest-count candidate, ties broken by the lowest sample index.
[decision] No usable candidate: the first PARSEABLE candidate (if any) is handed to the driver as it is,
so EB's own rule for it applies (out-of-range first id -> one invalid action on ALFRED/Habitat; an
empty plan -> the episode ends, or a random action on EB-Navigation); with nothing parseable the step is
one unparseable output (EB's `-1`: one invalid action, or a random action on EB-Navigation).
[decision] Empty plans are dropped as candidates (§3 lists only unparseable and out-of-range-first-id):
EB's guidelines forbid an empty plan and it would end an ALFRED/Habitat episode, so a non-empty
alternative is always preferred; it is still what runs when every candidate is empty.
[decision] The selector is shown action NAMES from the episode's list for each candidate's ids (EB
executes by id, so the written name may disagree), and no worked examples (§3 lists rules, actions,
instruction, observation and history as its context).
[decision] The selector runs on the planner's model (role "selector" borrows the planner's backend
when the run maps no model to it): BoN has no second model in the paper.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import Field

from worldmind_local.agent.driver import Episode
from worldmind_local.agent.plan import Plan, PlanParseError, extract_first_json_object, parse_plan
from worldmind_local.agent.prompting import (
    action_list,
    env_prior,
    format_history,
    load_template,
    render,
    user_content,
)
from worldmind_local.methods.base import BaseMethod, MethodConfig, Proposal
from worldmind_local.methods.react import eb_examples, react_messages, react_schema

__all__ = ["BestOfN", "BoNConfig", "Candidate", "selector_schema"]

MAX_ANALYSIS_CHARS = 1200


class BoNConfig(MethodConfig):
    """§3 (4): N=5 (SimuRA's number of simulated candidates), T_s=0.7 (reasoning-bank's acting T),
    selector T=0 and ReAct's token budget. All [decision]: BoN has no reference code."""

    n_candidates: int = Field(5, ge=1, le=64, description="BoN: plans sampled per planning step (one request, n=N)")
    sample_temperature: float = Field(0.7, ge=0.0, le=2.0, description="BoN: temperature of the N sampled plans")
    sample_top_p: float = Field(1.0, gt=0.0, le=1.0, description="BoN: top_p of the N sampled plans")
    selector_temperature: float = Field(0.0, ge=0.0, le=2.0, description="BoN: selector temperature")
    selector_max_tokens: int = Field(2048, ge=16, le=32768, description="BoN: selector token budget")


@dataclass(frozen=True, slots=True)
class Candidate:
    """One distinct usable plan: its ids, the samples that proposed it, and the first such sample."""

    ids: tuple[int, ...]
    plan: Plan
    raw: str
    first_sample: int
    count: int


def selector_schema(n_candidates: int) -> dict[str, Any]:
    """`{analysis, best_index}`; the index bounded to the numbered candidates (1-based)."""
    return {
        "type": "object",
        "properties": {
            "analysis": {"type": "string", "maxLength": MAX_ANALYSIS_CHARS},
            "best_index": {"type": "integer", "minimum": 1, "maximum": max(n_candidates, 1)},
        },
        "required": ["analysis", "best_index"],
        "additionalProperties": False,
    }


def _screen(text: str, n_actions: int) -> tuple[Plan | None, str]:
    """(plan, status): ok | malformed | empty | invalid_first_id."""
    try:
        plan = parse_plan(text)
    except PlanParseError:
        return None, "malformed"
    if plan.empty:
        return plan, "empty"
    if not 0 <= plan.actions[0].action_id < n_actions:
        return plan, "invalid_first_id"
    return plan, "ok"


def merge_candidates(texts: list[str], n_actions: int) -> tuple[list[Candidate], list[dict[str, Any]]]:
    """Distinct usable candidates in order of first appearance, and one log line per sample."""
    groups: dict[tuple[int, ...], Candidate] = {}
    log: list[dict[str, Any]] = []
    for i, text in enumerate(texts):
        plan, status = _screen(text, n_actions)
        ids = tuple(a.action_id for a in plan.actions) if plan is not None else ()
        log.append({"sample": i, "status": status, "ids": list(ids), "raw": text})
        if plan is None or status != "ok":
            continue
        seen = groups.get(ids)
        groups[ids] = Candidate(ids, plan, text, i, 1) if seen is None else \
            Candidate(ids, seen.plan, seen.raw, seen.first_sample, seen.count + 1)
    return list(groups.values()), log


def majority(candidates: list[Candidate]) -> int:
    """The fallback pick: highest count, ties to the lowest sample index (a position in `candidates`)."""
    return min(range(len(candidates)), key=lambda k: (-candidates[k].count, candidates[k].first_sample))


def _describe(candidate: Candidate, number: int, actions: list[str]) -> str:
    names = [f"{a.action_id}: {actions[a.action_id] if 0 <= a.action_id < len(actions) else 'out of range'}"
             for a in candidate.plan.actions]
    plan = candidate.plan.language_plan.strip() or "(no plan in words)"
    return f"### Candidate {number}\nPlan in words: {plan}\nActions (id: name): " + "; ".join(names)


def selector_messages(ep: Episode, candidates: list[Candidate], max_plan_actions: int) -> list[dict[str, Any]]:
    """The selector's view: the planner's rules, actions, instruction, observation and history, plus the
    numbered candidates. Built only from what `ep.planner_view()` allows and the trajectory's feedback."""
    text, image = ep.planner_view()
    system = render(load_template("common", "bon_selector_system"),
                    env_prior=env_prior(ep.env.benchmark, max_plan_actions=max_plan_actions),
                    max_action_id=len(ep.actions) - 1, action_list=action_list(ep.actions),
                    n_candidates=len(candidates))
    observation = f"\n## What you observe now\n{text.strip() or '(no description available)'}\n" if text else ""
    user = render(load_template("common", "bon_selector_user"), instruction=ep.task.instruction.strip(),
                  observation=observation,
                  history=format_history(ep.trajectory, ep.actions) or "(none yet: this is the first step)",
                  candidates="\n\n".join(_describe(c, k + 1, ep.actions) for k, c in enumerate(candidates)),
                  n_candidates=len(candidates))
    return [{"role": "system", "content": system},
            {"role": "user", "content": user_content(user, [image] if image is not None else [])}]


def parse_selection(text: str, n_candidates: int) -> int | None:
    """The chosen position (0-based) or None when the answer or its index is unusable."""
    try:
        value = extract_first_json_object(text).get("best_index")
    except PlanParseError:
        return None
    if isinstance(value, str) and value.strip().isdigit():
        value = int(value.strip())
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= n_candidates:
        return None
    return value - 1


class BestOfN(BaseMethod):
    name: ClassVar[str] = "bon"
    description: ClassVar[str] = "BoN: N sampled ReAct plans per planning step, an LLM selector picks one"
    memory_scope: ClassVar[Any] = "episodic"
    config_class: ClassVar[type[MethodConfig]] = BoNConfig
    config: BoNConfig

    async def start(self, ep: Episode) -> None:
        ep.state["examples"] = eb_examples(ep, self.config.n_shots)

    async def plan(self, ep: Episode) -> Proposal:
        cfg, index = self.config, len(ep.record.plans)
        messages = react_messages(ep, examples=ep.state["examples"], max_plan_actions=cfg.max_plan_actions)
        visual = ep.planner_view()[1] is not None
        key = f"planner:{index}"
        request = ep.calls.request("planner", messages, call_key=key, max_tokens=cfg.planner_max_tokens,
                                   json_schema=react_schema(len(ep.actions), cfg.max_plan_actions, visual=visual),
                                   temperature=cfg.sample_temperature, top_p=cfg.sample_top_p,
                                   n=cfg.n_candidates)
        result = await ep.calls.ask(request, call_key=key)
        candidates, log = merge_candidates(list(result.texts), len(ep.actions))
        extra: dict[str, Any] = {"bon": {"samples": log, "distinct": [
            {"ids": list(c.ids), "count": c.count, "first_sample": c.first_sample} for c in candidates]}}
        if not candidates:
            return self._nothing_usable(result, log, extra)
        pick, selector = 0, {"called": False}
        if len(candidates) > 1:
            pick, selector = await self._select(ep, index, candidates)
        chosen = candidates[pick]
        extra["bon"].update(selector=selector, pick=chosen.first_sample, pick_ids=list(chosen.ids))
        return Proposal(chosen.plan, result, chosen.raw, extra=extra)

    async def _select(self, ep: Episode, index: int, candidates: list[Candidate]) -> tuple[int, dict[str, Any]]:
        """One selector request at T=0; an unusable answer falls back to the majority candidate."""
        cfg, key = self.config, f"selector:{index}"
        request = ep.calls.request("selector", selector_messages(ep, candidates, cfg.max_plan_actions),
                                   call_key=key, max_tokens=cfg.selector_max_tokens,
                                   json_schema=selector_schema(len(candidates)), temperature=cfg.selector_temperature)
        result = await ep.calls.ask(request, call_key=key)
        chosen = parse_selection(result.text, len(candidates))
        info: dict[str, Any] = {"called": True, "raw": result.text, "valid": chosen is not None}
        if chosen is None:
            chosen = majority(candidates)
            info["fallback"] = "majority"
        return chosen, info

    @staticmethod
    def _nothing_usable(result: Any, log: list[dict[str, Any]], extra: dict[str, Any]) -> Proposal:
        """No candidate survived: hand the driver the first parseable one (EB's rule then applies to it),
        else report one unparseable output."""
        for line in log:
            if line["status"] != "malformed":
                plan = parse_plan(line["raw"])
                extra["bon"].update(selector={"called": False}, pick=line["sample"], fallback="first_parseable")
                return Proposal(plan, result, line["raw"], extra=extra)
        extra["bon"].update(selector={"called": False}, pick=None, fallback="none_parseable")
        raw = result.texts[0] if result.texts else ""
        return Proposal(None, result, raw, error=f"none of the {len(log)} sampled plans parses", extra=extra)
