"""rv_te_bench.cli."""
