"""Prompt templates: eb_alfred."""
