"""Prompt templates: common."""
