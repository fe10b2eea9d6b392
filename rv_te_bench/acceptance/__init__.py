"""Acceptance testing of a unit: test plans, tolerance profiles, step runners, verdicts.

No rclpy here: the ``test_sequencer`` node and ``rv-te test`` use these, and so does the
offline runner (:func:`run_plan_offline`) that drives the simulated bench directly.
"""

from __future__ import annotations

from rv_te_bench.acceptance.plan import (
    DIRECTIONS,
    HysteresisStep,
    SweepStep,
    TeStep,
    TestPlan,
    load_plan,
    parse_plan,
    shipped_plans,
)
from rv_te_bench.acceptance.runner import StepRunner, build_report, run_plan_offline
from rv_te_bench.acceptance.tolerance import (
    Measured,
    MetricVerdict,
    ToleranceProfile,
    evaluate,
    load_tolerance,
    parse_tolerance,
    shipped_tolerances,
)

__all__ = [
    'DIRECTIONS',
    'HysteresisStep',
    'Measured',
    'MetricVerdict',
    'StepRunner',
    'SweepStep',
    'TeStep',
    'TestPlan',
    'ToleranceProfile',
    'build_report',
    'evaluate',
    'load_plan',
    'load_tolerance',
    'parse_plan',
    'parse_tolerance',
    'run_plan_offline',
    'shipped_plans',
    'shipped_tolerances',
]
