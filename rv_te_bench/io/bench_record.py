"""What a bench recorded about itself (``BenchInfo.parameters_yaml``), read back bounded.

The text comes from a bag or from the network: it is parsed by the suite's bounded loader
(:mod:`rv_te_bench.safe_yaml`), so a hostile record costs at most its limits.
"""

from __future__ import annotations

from rv_te_bench.errors import YamlInputError
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

__all__ = ['PARAMETERS_YAML_LIMITS', 'overrides_from_parameters_yaml']

#: A BenchInfo record holds the preset's values and the bench settings: a few kB.
PARAMETERS_YAML_LIMITS = DOCUMENT_LIMITS


def overrides_from_parameters_yaml(text: str) -> list[str]:
    """The preset overrides a bench ran with, from ``BenchInfoData.parameters_yaml``.

    The inverse of what :attr:`sim.bench.BenchSimulator.info` records (``bench.overrides``),
    so that a consumer of a live BenchInfo or of a bag can rebuild the bench's exact preset.
    Anything unreadable, over the limits or not a list of scalars gives ``[]`` (the base
    preset).
    """
    if not text:
        return []
    try:
        record = load_yaml(text, origin='BenchInfo.parameters_yaml',
                           limits=PARAMETERS_YAML_LIMITS)
    except YamlInputError:
        return []
    bench = record.get('bench') if isinstance(record, dict) else None
    overrides = bench.get('overrides') if isinstance(bench, dict) else None
    if not isinstance(overrides, list) or not all(
            isinstance(o, str | int | float) for o in overrides):
        return []
    return [str(o) for o in overrides]
