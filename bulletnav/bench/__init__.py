"""Benchmarks that return JSON-ready dicts (the CLI prints them)."""
