"""What a bench recorded about itself: the BenchInfo record, one shape, read back bounded.

* :func:`bench_info_values`: the fields of :class:`sim.bench.BenchInfoData` (the one list of
  them) as plain Python values, from a ``BenchInfo`` message or a ``BenchInfoData``;
* :func:`overrides_from_parameters_yaml` and :func:`preset_from_bench_info`: the preset a
  bench ran with, rebuilt from its ``parameters_yaml``. The text comes from a bag or from
  the network: it is parsed by the suite's bounded loader (:mod:`rv_te_bench.safe_yaml`),
  so a hostile record costs at most its limits.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import TYPE_CHECKING, Any

from rv_te_bench.errors import YamlInputError
from rv_te_bench.safe_yaml import DOCUMENT_LIMITS, load_yaml

if TYPE_CHECKING:
    from collections.abc import Callable, Sequence

    from sim.presets import Preset

__all__ = ['PARAMETERS_YAML_LIMITS', 'bench_info_field_names', 'bench_info_values',
           'overrides_from_parameters_yaml', 'preset_from_bench_info']

#: BenchInfoData annotation -> conversion to the plain value (arrays as lists)
_PLAIN: dict[str, Callable[[Any], Any]] = {
    'str': str, 'float': float, 'int': int,
    'tuple[float, ...]': lambda v: [float(x) for x in v],
    'tuple[str, ...]': lambda v: [str(x) for x in v],
}


@functools.cache
def _bench_info_fields() -> tuple[tuple[str, Callable[[Any], Any]], ...]:
    from sim.bench import BenchInfoData  # noqa: PLC0415 - keeps sim.bench out of io's import

    return tuple((f.name, _PLAIN[str(f.type)]) for f in dataclasses.fields(BenchInfoData))


def bench_info_field_names() -> tuple[str, ...]:
    """The fields of ``rv_te_msgs/BenchInfo`` without the header, in message order."""
    return tuple(name for name, _ in _bench_info_fields())


def bench_info_values(info: Any) -> dict[str, Any]:  # noqa: ANN401 - message or dataclass
    """A BenchInfo's fields as plain values: ``str``, ``float``, ``int``, arrays as lists.

    Args:
        info: Anything with the attributes of :class:`sim.bench.BenchInfoData`: a
            ``BenchInfo`` message (rclpy or rosbags) or the dataclass itself.
    """
    return {name: plain(getattr(info, name)) for name, plain in _bench_info_fields()}

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


def preset_from_bench_info(preset: str, parameters_yaml: str,
                           extra_overrides: Sequence[str] = ()) -> Preset:
    """The preset a bench ran with: ``preset`` with the overrides it recorded, then ``extra``.

    Raises:
        PresetError: Unknown preset or a bad override (``sim.errors``).
    """
    from sim.presets import load_preset  # noqa: PLC0415

    return load_preset(preset, [*overrides_from_parameters_yaml(parameters_yaml),
                                *extra_overrides])
