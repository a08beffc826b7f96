"""Benchmarks: the figures of BENCHMARKS.md. Above the core: only the CLI and tests import them."""
