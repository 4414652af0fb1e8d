"""Registries with lazy targets: nothing heavy is imported until it is asked for.

A target is a string "package.module:Name". `import worldmind_local` therefore works with none of
vllm, torch, ai2thor or habitat installed. The `Registry` class and the backend registry live in
`models.registry` (the model layer stands on its own); benchmarks and methods are registered here.
"""

from __future__ import annotations

from models.registry import BACKENDS, Registry, load_target

__all__ = ["Registry", "BENCHMARKS", "BACKENDS", "METHODS", "load_target"]

BENCHMARKS = Registry("benchmark")
BENCHMARKS.register("eb_alfred", "benchmarks.eb_alfred:ADAPTER")
BENCHMARKS.register("eb_habitat", "benchmarks.eb_habitat:ADAPTER")
BENCHMARKS.register("eb_navigation", "benchmarks.eb_navigation:ADAPTER")

METHODS = Registry("method")
METHODS.register("worldmind", "worldmind_local.methods.worldmind:WorldMind")
# The paper's ablations (Table "Ablation Study" and the controlled memory ablation), one name each.
METHODS.register("worldmind_goal_only", "worldmind_local.methods.worldmind:WorldMindGoalOnly")
METHODS.register("worldmind_process_only", "worldmind_local.methods.worldmind:WorldMindProcessOnly")
METHODS.register("worldmind_no_verifier", "worldmind_local.methods.worldmind:WorldMindNoVerifier")
METHODS.register("worldmind_baseline", "worldmind_local.methods.worldmind:WorldMindBaseline")
# The paper's baselines (baselines.md), each one module under methods/.
METHODS.register("react", "worldmind_local.methods.react:ReAct")
METHODS.register("bon", "worldmind_local.methods.bon:BestOfN")
METHODS.register("simura", "worldmind_local.methods.simura:SimuRA")
METHODS.register("naivemem", "worldmind_local.methods.naivemem:NaiveMem")
METHODS.register("synapse", "worldmind_local.methods.synapse:Synapse")
METHODS.register("awm", "worldmind_local.methods.awm:AgentWorkflowMemory")
METHODS.register("reasoningbank", "worldmind_local.methods.reasoningbank:ReasoningBank")
