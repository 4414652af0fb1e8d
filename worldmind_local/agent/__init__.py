"""The agent layer: the generic episode driver (EmbodiedBench's evaluator protocol), planner output
parsing, prompts, and WorldMind's roles around the planner (StateAbstractor, Judge, Reflector,
GoalDistiller, ExperienceRefiner) that methods compose."""

from worldmind_local.agent.abstractor import AbstractState, StateAbstractor
from worldmind_local.agent.calls import ModelCalls, derive_seed
from worldmind_local.agent.distiller import GoalDistiller, annotate_trajectory
from worldmind_local.agent.driver import Episode, EpisodeOutcome, run_episode
from worldmind_local.agent.judge import Judge, Verdict, parse_verdict
from worldmind_local.agent.plan import (
    SKIP_STRING,
    Plan,
    PlannedAction,
    PlanParseError,
    parse_plan,
    planner_schema,
)
from worldmind_local.agent.prompting import load_template, planner_messages, render
from worldmind_local.agent.reflector import Reflection, Reflector, parse_rules

__all__ = [
    "SKIP_STRING",
    "AbstractState",
    "Episode",
    "EpisodeOutcome",
    "run_episode",
    "GoalDistiller",
    "Judge",
    "ModelCalls",
    "Plan",
    "PlanParseError",
    "PlannedAction",
    "Reflection",
    "Reflector",
    "StateAbstractor",
    "Verdict",
    "annotate_trajectory",
    "derive_seed",
    "load_template",
    "parse_plan",
    "parse_rules",
    "parse_verdict",
    "planner_messages",
    "planner_schema",
    "render",
]
