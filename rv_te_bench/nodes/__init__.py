"""rv_te_bench.nodes."""
