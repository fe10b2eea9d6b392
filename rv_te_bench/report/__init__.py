"""Offline reports of recorded TE sessions: analysis, figures, HTML page.

No rclpy: everything here runs on a laptop without ROS.
"""

from __future__ import annotations

from rv_te_bench.report.analysis import (
    AnalysisBench,
    AnalysisResult,
    DominantHarmonic,
    Recommendation,
    SpectrumSummary,
    TeTrace,
    analyze_bag,
    compare_results,
    likely_source,
)

__all__ = [
    'AnalysisBench',
    'AnalysisResult',
    'DominantHarmonic',
    'Recommendation',
    'SpectrumSummary',
    'TeTrace',
    'analyze_bag',
    'compare_results',
    'likely_source',
]
