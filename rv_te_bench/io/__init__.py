"""rv_te_bench.io."""
