"""Methods: the policy around the planner. Each method is one module; the runner finds them through
`worldmind_local.registry.METHODS` (lazy targets such as "worldmind_local.methods.worldmind:WorldMind")."""

from worldmind_local.methods.base import EpisodeContext, Method, MethodConfig

__all__ = ["EpisodeContext", "Method", "MethodConfig"]
