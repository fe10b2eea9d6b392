"""Start a node process of a session: ``python -m rv_te_bench.nodes._entry MODULE ARGS...``.

The launcher stops its nodes with SIGINT. One that arrives while a node process still
imports (rclpy, numpy: about a second) used to end in a KeyboardInterrupt traceback in the
session's output; here it ends the process quietly with exit code 130, as Ctrl-C does once
the node runs (:func:`rv_te_bench.nodes.common.run_node`).
"""

from __future__ import annotations

import importlib
import sys


def main() -> int:
    """Import the node module named by the first argument and run its ``main``."""
    module = sys.argv[1]
    try:
        node_main = importlib.import_module(module).main
    except KeyboardInterrupt:
        print(f'{module}: interrupted while starting', file=sys.stderr)
        return 130
    sys.argv = [module, *sys.argv[2:]]
    return int(node_main() or 0)


if __name__ == '__main__':
    sys.exit(main())
