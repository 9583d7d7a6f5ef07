"""Helpers of the benchmark suite (``benchmarks/suite.py``): frames, timing, quality, Open3D, node."""
