"""rv_te_bench.launch."""
