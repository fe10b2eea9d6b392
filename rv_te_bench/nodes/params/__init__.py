"""Each node's parameters as a frozen record, one module per node (no rclpy)."""

#: Environment variable naming the file where a node process that ends with an error leaves
#: its reason (one line). The launcher (:class:`rv_te_bench.launch.session.Session`) sets it
#: per node, so that the session's failure line says why, not only the exit code.
FAILURE_FILE_ENV = 'RV_TE_NODE_FAILURE_FILE'
#: Environment variable naming the file where a stopping node process notes what it is
#: doing (one line, replaced at each step of its stop): a launcher that gives up waiting
#: for it says where it was (:meth:`rv_te_bench.launch.session.Session.stop`).
STOP_PHASE_FILE_ENV = 'RV_TE_NODE_STOP_PHASE_FILE'
