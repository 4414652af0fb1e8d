"""`--perturb rename`: the paper's object-rename stress test ("Object Rename replaces 32 object names with
synonyms in textual env_feedback while preserving the simulator state and action parser").

What it does, and why it is built this way:

- It changes only what the environment *says*: every `StepResult.feedback` and every `Observation.text`
  (the abstract state the judge compares a prediction against, and what a text planner may be shown)
  goes through the synonym table in `rename_tables.json` ("Cannot find Mug" -> "Cannot find stein").
- It never changes what the environment *is* or *accepts*: the simulator state (`Observation.state`,
  success, progress, limits) is the unwrapped env's, and `env.actions` - the action list the planner
  sees and the parser reads its answers against - keeps the env's exact names. So a planner that
  writes "pick up the Mug" is still understood, and SR/GC are measured on exactly the same tasks as a
  clean run. The shift is a surface-form one: the agent is told about a "stein" but must act on the
  "Mug", which is what the paper's robustness table measures (how much experience helps the agent
  keep grounding when feedback wording drifts).
- The instruction (the task) and the few-shot examples are left alone: the paper perturbs env feedback,
  not the dataset or the prompt.

Matching is whole-name, case-insensitive, and also accepts the name's words separated by spaces
("ButterKnife", "Butterknife", "butter knife"), a plural "s"/"es", and EB's instance suffix
("Cabinet_2" -> "cupboard_2"). All names are replaced in one pass, longest first, so a synonym is never
renamed again and "Pot" never touches "Potato".
"""

from __future__ import annotations

import functools
import json
import re
from dataclasses import replace
from importlib import resources
from typing import Any

from worldmind_local.env import Observation, StepResult, Task

__all__ = ["rename_table", "Renamer", "RenamedEnv", "RenamedAdapter"]


@functools.lru_cache(maxsize=1)
def _tables() -> dict[str, dict[str, str]]:
    text = resources.files("worldmind_local.perturb").joinpath("rename_tables.json").read_text()
    return {k: v for k, v in json.loads(text).items() if not k.startswith("_")}


def rename_table(benchmark: str) -> dict[str, str]:
    """The shipped type -> synonym table of a benchmark (KeyError names the benchmarks that have one)."""
    tables = _tables()
    if benchmark not in tables:
        raise KeyError(f"no rename table for benchmark {benchmark!r}; tables: {', '.join(sorted(tables))}")
    return dict(tables[benchmark])


def _name_pattern(name: str) -> str:
    """A regex for `name`: its CamelCase/space-separated words with optional spaces between them."""
    words = re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|\d+|\S+?", name.replace(" ", "\0"))
    words = [w for w in words if w != "\0"]
    return r" ?".join(re.escape(w) for w in words)


class Renamer:
    """Replaces every object name of a table in a text, in one pass."""

    def __init__(self, table: dict[str, str]) -> None:
        self.table = table
        names = sorted(table, key=len, reverse=True)
        self._lookup = {re.sub(r"\s+", "", n).casefold(): n for n in names}
        alternatives = "|".join(f"(?:{_name_pattern(n)})" for n in names)
        self._regex = re.compile(rf"(?<![A-Za-z])(?P<name>{alternatives})(?P<plural>e?s)?(?![A-Za-z])",
                                 re.IGNORECASE)

    def _sub(self, match: re.Match[str]) -> str:
        found = match.group("name")
        name = self._lookup[re.sub(r"\s+", "", found).casefold()]
        synonym = self.table[name]
        if found[:1].isupper() and name[:1].islower():  # "Refrigerator: closed" (a lower-case name capitalised)
            synonym = synonym[:1].upper() + synonym[1:]
        return synonym + ("s" if match.group("plural") else "")

    def __call__(self, text: str) -> str:
        return self._regex.sub(self._sub, text) if text else text


class RenamedEnv:
    """An env whose feedback and observation text are renamed; state, actions and parsing are not."""

    def __init__(self, env: Any, renamer: Renamer) -> None:
        self._env = env
        self._renamer = renamer

    def __getattr__(self, name: str) -> Any:  # actions, max_steps, action_id, close, ...: the env's own
        if name.startswith("_"):  # never for private names: keeps pickling (env workers) from recursing
            raise AttributeError(name)
        return getattr(self._env, name)

    def _observation(self, obs: Observation) -> Observation:
        return Observation(lambda: self._renamer(obs.text), state=lambda: obs.state, image=obs.image)

    def reset(self, task: Task) -> Observation:
        return self._observation(self._env.reset(task))

    def step(self, action_id: int) -> StepResult:
        res = self._env.step(action_id)
        return replace(res, feedback=self._renamer(res.feedback), observation=self._observation(res.observation))


class RenamedAdapter:
    """A benchmark adapter whose envs are `RenamedEnv`s; everything else is the adapter's own."""

    def __init__(self, adapter: Any) -> None:
        self._adapter = adapter
        self.renamer = Renamer(rename_table(adapter.name))

    def __getattr__(self, name: str) -> Any:
        if name.startswith("_"):
            raise AttributeError(name)
        return getattr(self._adapter, name)

    def make_env(self, kind: str = "twin", **options: Any) -> RenamedEnv:
        return RenamedEnv(self._adapter.make_env(kind, **options), self.renamer)
