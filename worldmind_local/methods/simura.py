"""SimuRA: simulative reasoning with an LLM world model, one real action per planning step
(baselines.md §4; reference: ReasonerAgent-Web in llm-reasoners `f94e5ac`, `reasoners/agent/agent.py`,
`modules/planner.py`, `modules/planner_utils.py`, `algorithm/dfs.py`, `variables/memory.py`).

Per planning step (= per env step: SimuRA commits one action, depth 1):
1. encoder (1 request, T=0): latest env feedback + what the driver lets the planner see + instruction
   + history -> a natural-language `state` (location, held object, visible objects, open/closed);
2. policy (1 request, `n=policy_samples`=20, T=1.0, top_p 0.95): one next action per sample,
   `{think, action_id, action_name}`;
3. clustering: samples grouped by identical `action_id` and counted; the top `max_clusters`=5 clusters
   by count are kept (ties: smallest id);
4. one cluster: taken without simulation (reference `return_if_single_first_action=True`);
5. otherwise, per cluster, concurrently: a memory update on a copy of the memory (1 request), the world
   model predicting the state after the attempt, including whether it is valid and the likely feedback
   (1 request), and the critic (1 request, `n=critic_samples`=20, T=1.0, top_p 0.95) scoring each sample
   1 (success), 0.5 (on the right track) or 0; the cluster's reward is the mean;
6. depth-1 search: the highest reward wins; ties by cluster count, then smallest `action_id` (§4 (5));
7. actor: the identity (the intent IS an action of EB's list; no call);
8. the real memory update for the chosen action (1 request); (summary, intent) joins the episode's memory.

Requests per planning step: 3 (one cluster) to 3 + 3 * 5 = 18 (five clusters), as §4 (7) counts them;
2 when no policy sample is usable (then no action is chosen and the driver applies EB's policy for an
unusable output: one invalid action on ALFRED/Habitat, a random action on EB-Navigation). Defaults are
the reference's (`configs.py` `browsergym_world_model`: 20 policy / 20 critic samples, 5 actions,
depth 1; `planner_utils.py`: policy/critic T=1.0, top_p 0.95; `utils/config.py`: other modules T=0,
top_p 0.5); every one is a config field. Memory is per episode; nothing crosses episodes. Modules see
EB's action/feedback history (every method gets it) plus SimuRA's step summaries, never `info`
(success/progress); the world model is never shown a real post-step outcome.

[decision] Clustering is grouping by identical `action_id` (§4 (5)): deterministic and no LLM call. The
reference's LLM clustering call merges intents "that map to the same executed call"; EB's skills already
ARE the executed calls, so exact-id grouping is that criterion, and the reference's clustering and actor
requests (the web agent's +2) are not made.
[decision] Identity = EB's rules and indexed action list without the n-shot examples (`n_shots` defaults
to 0 here; setting it adds EB's examples to every module's system message, logged in the config).
[decision] Modules answer JSON under a schema instead of the reference's XML tags, since every backend
here enforces schemas (C3); the reference's up-to-4 parse retries are not made (they would break the
3-18 request range): an unparseable encoder / memory / world-model answer is used as plain text, an
unparseable policy sample is dropped, and an unparseable critic sample is left out of the mean (a
cluster with no parseable critic sample scores 0).
[decision] Out-of-range policy ids are dropped (the schema bounds them anyway): an action that cannot be
executed is not an intent.
[decision] Every module runs on the planner's model (roles encoder, world_model, critic, memory_update
borrow the planner's backend when the run maps none), as the reference runs one LLM throughout.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass
from typing import Any, ClassVar

from pydantic import Field

from worldmind_local.agent.driver import Episode
from worldmind_local.agent.plan import Plan, PlannedAction, PlanParseError, extract_first_json_object
from worldmind_local.agent.prompting import (
    action_list,
    env_prior,
    format_history,
    load_template,
    render,
    user_content,
)
from worldmind_local.methods.base import BaseMethod, MethodConfig, Proposal
from worldmind_local.methods.react import eb_examples

__all__ = ["SimuRA", "SimuRAConfig", "Cluster", "cluster_samples", "critic_score"]

MODULE_ROLES = ("encoder", "world_model", "critic", "memory_update")
MAX_STATE_CHARS = 1200
MAX_NOTE_CHARS = 600
MAX_THINK_CHARS = 600
MODULE_TEXT = {
    "encoder": "the encoder, which turns what the robot perceives into a description of its situation.",
    "policy": "the policy, which proposes the robot's next action.",
    "memory_update": "the memory, which notes what each step changed and achieved.",
    "world_model": "the world model, which predicts what an action would lead to before the robot tries it.",
    "critic": "the critic, which judges an imagined situation against the instruction.",
}


class SimuRAConfig(MethodConfig):
    """§4 (4) defaults: the reference's sample counts, temperatures and search shape. The base config's
    `temperature`, `planner_max_tokens` and `max_plan_actions` do not apply: the policy has its own
    `policy_*` settings and a plan is always one action."""

    n_shots: int | None = Field(0, ge=0, le=20, description="in-context examples (SimuRA default 0: its identity has none)")
    policy_samples: int = Field(20, ge=1, le=64, description="SimuRA: policy samples per step (one request, n)")
    critic_samples: int = Field(20, ge=1, le=64, description="SimuRA: critic samples per simulated action (n)")
    max_clusters: int = Field(5, ge=1, le=20, description="SimuRA: distinct actions simulated per step")
    policy_temperature: float = Field(1.0, ge=0.0, le=2.0, description="SimuRA: policy temperature")
    policy_top_p: float = Field(0.95, gt=0.0, le=1.0, description="SimuRA: policy top_p")
    critic_temperature: float = Field(1.0, ge=0.0, le=2.0, description="SimuRA: critic temperature")
    critic_top_p: float = Field(0.95, gt=0.0, le=1.0, description="SimuRA: critic top_p")
    module_temperature: float = Field(0.0, ge=0.0, le=2.0,
                                      description="SimuRA: encoder/memory/world-model temperature")
    module_top_p: float = Field(0.5, gt=0.0, le=1.0, description="SimuRA: encoder/memory/world-model top_p")
    return_if_single: bool = Field(True, description="SimuRA: skip simulation when the policy agrees on one action")
    encoder_max_tokens: int = Field(512, ge=16, le=8192, description="SimuRA: encoder token budget")
    policy_max_tokens: int = Field(384, ge=16, le=8192, description="SimuRA: policy token budget per sample")
    memory_max_tokens: int = Field(384, ge=16, le=8192, description="SimuRA: memory-update token budget")
    world_model_max_tokens: int = Field(512, ge=16, le=8192, description="SimuRA: world-model token budget")
    critic_max_tokens: int = Field(384, ge=16, le=8192, description="SimuRA: critic token budget per sample")


@dataclass(slots=True)
class Cluster:
    """One distinct proposed action: how many policy samples chose it and the first one's reasoning."""

    action_id: int
    action_name: str
    count: int
    first_sample: int
    think: str
    raw: str
    reward: float | None = None


def _text_schema(key: str, max_chars: int) -> dict[str, Any]:
    return {"type": "object", "properties": {key: {"type": "string", "maxLength": max_chars}},
            "required": [key], "additionalProperties": False}


def policy_schema(n_actions: int) -> dict[str, Any]:
    return {
        "type": "object",
        "properties": {
            "think": {"type": "string", "maxLength": MAX_THINK_CHARS},
            "action_id": {"type": "integer", "minimum": 0, "maximum": max(n_actions - 1, 0)},
            "action_name": {"type": "string", "maxLength": 80},
        },
        "required": ["think", "action_id", "action_name"],
        "additionalProperties": False,
    }


CRITIC_SCHEMA: dict[str, Any] = {
    "type": "object",
    "properties": {
        "think": {"type": "string", "maxLength": MAX_THINK_CHARS},
        "status": {"type": "string", "enum": ["success", "failure"]},
        "on_the_right_track": {"type": "string", "enum": ["yes", "no"]},
    },
    "required": ["think", "status", "on_the_right_track"],
    "additionalProperties": False,
}


def _field(text: str, key: str) -> Any:
    try:
        return extract_first_json_object(text).get(key)
    except PlanParseError:
        return None


def text_field(text: str, key: str, limit: int) -> str:
    """A module's text answer; the raw text when it does not parse (no retries, see [decision])."""
    value = _field(text, key)
    out = value if isinstance(value, str) and value.strip() else text
    return out.strip()[:limit] or "(nothing)"


def cluster_samples(texts: list[str], actions: list[str], max_clusters: int) -> tuple[list[Cluster], list[dict]]:
    """Group policy samples by identical `action_id`; the top `max_clusters` by count (ties: smallest
    id). Also one log line per sample."""
    clusters: dict[int, Cluster] = {}
    log: list[dict[str, Any]] = []
    for i, text in enumerate(texts):
        value = _field(text, "action_id")
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value < len(actions):
            log.append({"sample": i, "action_id": value if isinstance(value, int) else None, "usable": False})
            continue
        log.append({"sample": i, "action_id": value, "usable": True})
        if value in clusters:
            clusters[value].count += 1
            continue
        think = _field(text, "think")
        clusters[value] = Cluster(value, actions[value], 1, i, think.strip() if isinstance(think, str) else "", text)
    ranked = sorted(clusters.values(), key=lambda c: (-c.count, c.action_id))
    return ranked[:max_clusters], log


def critic_score(text: str) -> float | None:
    """1 for success, else 0.5 when on the right track, else 0 (reference `planner_utils.py`);
    None when the sample does not parse."""
    try:
        obj = extract_first_json_object(text)
    except PlanParseError:
        return None
    status, track = obj.get("status"), obj.get("on_the_right_track")
    if not isinstance(status, str) or not isinstance(track, str):
        return None
    if status.strip().lower() == "success":
        return 1.0
    return 0.5 if track.strip().lower() == "yes" else 0.0


def best_cluster(clusters: list[Cluster]) -> Cluster:
    """Highest reward; ties by cluster count, then smallest action id (§4 (5))."""
    return min(clusters, key=lambda c: (-(c.reward or 0.0), -c.count, c.action_id))


def intent_text(cluster: Cluster) -> str:
    return f"action id {cluster.action_id}: {cluster.action_name}"


class SimuRA(BaseMethod):
    name: ClassVar[str] = "simura"
    description: ClassVar[str] = ("SimuRA: encoder, sampled policy, LLM world model and critic; "
                                  "one simulated-best action per step")
    memory_scope: ClassVar[Any] = "episodic"
    config_class: ClassVar[type[MethodConfig]] = SimuRAConfig
    config: SimuRAConfig

    async def start(self, ep: Episode) -> None:
        ep.state.update(examples=eb_examples(ep, self.config.n_shots), memory=[],
                        stats=Counter(simulated_steps=0, single_cluster_steps=0, no_usable_sample_steps=0))

    async def finish(self, ep: Episode) -> None:
        ep.record.method_stats = dict(ep.state.get("stats") or {})

    # -- prompts ----------------------------------------------------------------------------------

    def _system(self, ep: Episode, module: str) -> str:
        examples = ep.state.get("examples") or ""
        return render(load_template("common", "simura_identity"), module=MODULE_TEXT[module],
                      env_prior=env_prior(ep.env.benchmark, max_plan_actions=1),
                      max_action_id=len(ep.actions) - 1, action_list=action_list(ep.actions),
                      examples=(f"\n# Task execution examples (from other tasks; their ids belong to their own "
                                f"episodes)\n{examples}\n" if examples else ""))

    def _messages(self, ep: Episode, module: str, template: str, image: Any = None, **values: Any) -> list[dict]:
        user = render(load_template("common", template), instruction=ep.task.instruction.strip(), **values)
        return [{"role": "system", "content": self._system(ep, module)},
                {"role": "user", "content": user_content(user, [image] if image is not None else [])}]

    @staticmethod
    def _history(ep: Episode) -> str:
        return format_history(ep.trajectory, ep.actions) or "(none yet: this is the first step)"

    @staticmethod
    def _memory(notes: list[tuple[str, str]]) -> str:
        lines = [f"Step {i}: {summary} (then: {intent})" for i, (summary, intent) in enumerate(notes)]
        return "\n".join(lines) or "(nothing yet)"

    async def _ask(self, ep: Episode, role: str, messages: list[dict], key: str, max_tokens: int,
                   schema: dict[str, Any], *, sampled: bool = False, n: int = 1) -> Any:
        cfg = self.config
        temperature = (cfg.policy_temperature if role == "planner" else cfg.critic_temperature) if sampled \
            else cfg.module_temperature
        top_p = (cfg.policy_top_p if role == "planner" else cfg.critic_top_p) if sampled else cfg.module_top_p
        request = ep.calls.request(role, messages, call_key=key, max_tokens=max_tokens, json_schema=schema,
                                   temperature=temperature, top_p=top_p, n=n)
        return await ep.calls.ask(request, call_key=key)

    # -- the modules ------------------------------------------------------------------------------

    async def _encode(self, ep: Episode, index: int) -> str:
        text, image = ep.planner_view()
        steps = [s for s in ep.trajectory if s.env_step]
        feedback = steps[-1].feedback if steps else "(none: the episode has just started)"
        observation = f"\n## What you observe now\n{text.strip() or '(no description available)'}\n" if text else ""
        messages = self._messages(ep, "encoder", "simura_encoder", image, observation=observation,
                                  feedback=feedback, history=self._history(ep))
        result = await self._ask(ep, "encoder", messages, f"encoder:{index}", self.config.encoder_max_tokens,
                                 _text_schema("state", MAX_STATE_CHARS))
        return text_field(result.text, "state", MAX_STATE_CHARS)

    async def _memory_update(self, ep: Episode, key: str, state: str, intent: str) -> str:
        messages = self._messages(ep, "memory_update", "simura_memory_update", history=self._history(ep),
                                  memory=self._memory(ep.state["memory"]), state=state, intent=intent)
        result = await self._ask(ep, "memory_update", messages, key, self.config.memory_max_tokens,
                                 _text_schema("memory_update", MAX_NOTE_CHARS))
        return text_field(result.text, "memory_update", MAX_NOTE_CHARS)

    async def _simulate(self, ep: Episode, index: int, state: str, cluster: Cluster) -> dict[str, Any]:
        """Memory update on a copy, world model, critic (n samples) for one candidate action."""
        cfg, intent, tag = self.config, intent_text(cluster), f"{index}:a{cluster.action_id}"
        note = await self._memory_update(ep, f"memory_update:{tag}", state, intent)
        memory = self._memory(ep.state["memory"])
        wm_messages = self._messages(ep, "world_model", "simura_world_model", history=self._history(ep),
                                     memory=memory, state=state, memory_update=note, intent=intent)
        wm = await self._ask(ep, "world_model", wm_messages, f"world_model:{tag}", cfg.world_model_max_tokens,
                             _text_schema("next_state", MAX_STATE_CHARS))
        next_state = text_field(wm.text, "next_state", MAX_STATE_CHARS)
        imagined = self._memory([*ep.state["memory"], (note, intent)])
        critic_messages = self._messages(ep, "critic", "simura_critic", history=self._history(ep),
                                         memory=imagined, state=next_state)
        critic = await self._ask(ep, "critic", critic_messages, f"critic:{tag}", cfg.critic_max_tokens,
                                 CRITIC_SCHEMA, sampled=True, n=cfg.critic_samples)
        scores = [critic_score(t) for t in critic.texts]
        parsed = [s for s in scores if s is not None]
        cluster.reward = sum(parsed) / len(parsed) if parsed else 0.0
        return {"action_id": cluster.action_id, "count": cluster.count, "memory_update": note,
                "next_state": next_state, "critic_scores": scores, "reward": cluster.reward}

    # -- one planning step ------------------------------------------------------------------------

    async def plan(self, ep: Episode) -> Proposal:
        cfg, index, stats = self.config, len(ep.record.plans), ep.state["stats"]
        state = await self._encode(ep, index)
        messages = self._messages(ep, "policy", "simura_policy", history=self._history(ep),
                                  memory=self._memory(ep.state["memory"]), state=state,
                                  max_action_id=len(ep.actions) - 1)
        policy = await self._ask(ep, "planner", messages, f"planner:{index}", cfg.policy_max_tokens,
                                 policy_schema(len(ep.actions)), sampled=True, n=cfg.policy_samples)
        clusters, log = cluster_samples(list(policy.texts), ep.actions, cfg.max_clusters)
        extra: dict[str, Any] = {"simura": {"state": state, "samples": log, "clusters": [
            {"action_id": c.action_id, "count": c.count} for c in clusters]}}
        if not clusters:
            stats["no_usable_sample_steps"] += 1
            raw = policy.texts[0] if policy.texts else ""
            return Proposal(None, policy, raw, error=f"none of the {len(log)} policy samples names an action",
                            extra=extra)
        if len(clusters) == 1 and cfg.return_if_single:
            stats["single_cluster_steps"] += 1
            chosen = clusters[0]
        else:
            stats["simulated_steps"] += 1
            extra["simura"]["simulations"] = list(await ep.calls.gather(
                *(self._simulate(ep, index, state, c) for c in clusters)))
            chosen = best_cluster(clusters)
        intent = intent_text(chosen)
        note = await self._memory_update(ep, f"memory_update:{index}", state, intent)
        ep.state["memory"].append((note, intent))
        extra["simura"].update(chosen=chosen.action_id, memory_update=note)
        plan = Plan(chosen.think, (PlannedAction(chosen.action_id, chosen.action_name, None, False),))
        return Proposal(plan, policy, chosen.raw, extra=extra)
