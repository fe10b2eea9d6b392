"""The compensation node's search worker process (:mod:`rv_te_bench.nodes.search_process`).

``python -m rv_te_bench.nodes._search_worker NICE``: its own module, so that the classes it
hands back pickle under their importable names (not ``__main__``'s).
"""

import sys

from rv_te_bench.nodes.search_process import worker_main

if __name__ == '__main__':
    sys.exit(worker_main())
