"""Each node's parameters as a frozen record, one module per node (no rclpy)."""
