"""Modules of the `tools/` scripts (a plain package: `tools/evaluate.py` imports it from its own folder)."""
