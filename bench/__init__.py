"""Benchmarks behind ``make bench``: each ``bench/bench_*.py`` exposes ``run(quick) -> Section``."""
