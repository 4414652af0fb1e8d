"""Prompt templates: eb_habitat."""
