"""Prompt text this benchmark owns (the env prior shared by every method's planner prompt)."""
