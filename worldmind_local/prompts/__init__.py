"""Prompt templates (Markdown), read with importlib.resources by worldmind_local.agent.prompting."""
