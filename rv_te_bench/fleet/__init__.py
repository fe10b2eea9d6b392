"""Analysis of many bags on a Dask cluster, results into the results store.

``discover_bags`` finds the bags under folders and glob patterns; ``run_fleet`` analyses
them on a local Dask cluster (or an existing scheduler) and writes one record per bag as
each result arrives. No rclpy here.
"""

from __future__ import annotations

from rv_te_bench.fleet._discover import discover_bags
from rv_te_bench.fleet._run import FleetOptions, FleetSummary, analyse_one, run_fleet

__all__ = ['FleetOptions', 'FleetSummary', 'analyse_one', 'discover_bags', 'run_fleet']
