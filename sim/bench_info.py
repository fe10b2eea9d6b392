"""The record a bench gives of itself: :class:`BenchInfoData`, the fields of BenchInfo.

The lowest floor of the bench's metadata: plain types, no numpy, no YAML, so that the
bag readers (:mod:`rv_te_bench.io`), the analysis core and the nodes can all take it
without pulling in the simulator. :mod:`sim.bench` builds it for a simulated bench.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from collections.abc import Callable

__all__ = ['DEFAULT_SAMPLE_RATE_HZ', 'BenchInfoData']

#: The one default DAQ sample rate [Hz]: the simulated bench (:class:`sim.bench.BenchConfig`),
#: the program bench (:class:`sim.program.ProgramSimulator`) and the bench node's parameter.
DEFAULT_SAMPLE_RATE_HZ = 1000.0

#: BenchInfoData annotation -> conversion of a message's value to the record's (arrays as
#: tuples of Python numbers / strings)
_FIELD_TYPES: dict[str, Callable[[Any], Any]] = {
    'str': str, 'float': float, 'int': int,
    'tuple[float, ...]': lambda v: tuple(float(x) for x in v),
    'tuple[str, ...]': lambda v: tuple(str(x) for x in v),
}


@dataclass(frozen=True, kw_only=True)
class BenchInfoData:
    """What a bench says about itself: the fields of ``rv_te_msgs/BenchInfo`` (no header).

    The one in-memory form of a bench's record, from the preset to the spectrum: the bench
    node publishes it, the recorder stores it, ``read_bench_info`` reads it back from a bag,
    and the TE node, the offline analysis and the acceptance runner take it. The field list
    is the message's (same names, same order; the wire format does not change), so a field
    added to the message is added here and the type checker finds its uses. Values are
    checked where they are used (:meth:`rv_te_bench.core.orders.OrderSet.from_bench_info`
    for the ratio and the crank order): a record read from a damaged bag is still a record.
    Every field but the ratio defaults to the message's own default ('', 0, empty): "not
    given" (a sample rate of 0 is unknown, not :data:`DEFAULT_SAMPLE_RATE_HZ`).

    Attributes:
        bench_id: Bench identifier (EncoderBlock ``frame_id``).
        preset: Reducer preset name ('' for a reducer described without one).
        reducer_type: ``'2kv'``, ``'rv'``, ``'other'`` or ''.
        gear_ratio: Overall ratio i, input revolutions per output revolution.
        crank_per_input: Absolute crank revolutions per input revolution, signed (the wire
            form; :meth:`~rv_te_bench.core.orders.OrderSet.from_bench_info` converts it to
            the crank order per output revolution).
        crank_rel_per_input: Crank revolutions relative to the carrier per input revolution.
        mesh_orders: Mesh frequencies as orders of the output rotation.
        mesh_labels: One label per mesh order.
        encoder_in_model: Input-shaft encoder model.
        encoder_out_model: Output-shaft encoder model.
        encoder_in_resolution_rad: Input encoder increment [rad] (0: unknown).
        encoder_out_resolution_rad: Output encoder increment [rad] (0: unknown).
        sample_rate_hz: Nominal DAQ rate [Hz].
        block_size: Samples per EncoderBlock.
        parameters_yaml: The bench settings and the preset's values as YAML.
    """

    bench_id: str = ''
    preset: str = ''
    reducer_type: str = ''
    gear_ratio: float
    crank_per_input: float = 0.0
    crank_rel_per_input: float = 0.0
    mesh_orders: tuple[float, ...] = ()
    mesh_labels: tuple[str, ...] = ()
    encoder_in_model: str = ''
    encoder_out_model: str = ''
    encoder_in_resolution_rad: float = 0.0
    encoder_out_resolution_rad: float = 0.0
    sample_rate_hz: float = 0.0
    block_size: int = 0
    parameters_yaml: str = ''

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The message's fields without the header, in message order."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_message(cls, msg: Any) -> BenchInfoData:
        """The record of a ``BenchInfo`` message (rclpy or rosbags) or anything alike.

        Args:
            msg: An object with every field of the record as an attribute (arrays as any
                sequence: ``array.array``, numpy, list).

        Raises:
            AttributeError: A field is missing.
            TypeError, ValueError: A value does not convert (a number that is no number).
        """
        return cls(**{f.name: _FIELD_TYPES[str(f.type)](getattr(msg, f.name))
                      for f in fields(cls)})

    def message_values(self) -> dict[str, Any]:
        """The fields as the message takes them: ``str``, ``float``, ``int``, lists."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}
