"""rv-te-bench: transmission-error testing of precision robot reducers.

``rv_te_bench.core`` and ``rv_te_bench.io`` never import rclpy; the nodes live in
``rv_te_bench.nodes``.
"""

from __future__ import annotations

__version__ = '0.1.0'
__all__ = ['__version__']
