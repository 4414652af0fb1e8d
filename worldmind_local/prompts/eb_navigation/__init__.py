"""Prompt templates: eb_navigation."""
