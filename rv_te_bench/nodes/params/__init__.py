"""Each node's parameters as a frozen record, one module per node (no rclpy)."""

#: Environment variable naming the file where a node process that ends with an error leaves
#: its reason (one line). The launcher (:class:`rv_te_bench.launch.session.Session`) sets it
#: per node, so that the session's failure line says why, not only the exit code.
FAILURE_FILE_ENV = 'RV_TE_NODE_FAILURE_FILE'
