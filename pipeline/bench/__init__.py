"""Benchmarks run by ``make bench`` (see pipeline/cli/bench.py)."""
