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


#: Fields issue 36 appended to the message (scales and read heads): absent from older bags.
_ADDED_FIELDS = frozenset({
    'encoder_in_head_angles_rad', 'encoder_out_head_angles_rad', 'encoder_in_scale_serial',
    'encoder_out_scale_serial', 'encoder_in_scale_diameter_m', 'encoder_out_scale_diameter_m',
    'encoder_in_scale_eccentricity_m', 'encoder_out_scale_eccentricity_m',
    'encoder_in_scale_index_rad', 'encoder_out_scale_index_rad'})


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
        encoder_in_head_angles_rad: Angle of each read head around the input scale from
            head 0 [rad] (empty: one head).
        encoder_out_head_angles_rad: The same for the output scale.
        encoder_in_scale_serial: Serial number of the input scale ('' : not stated).
        encoder_out_scale_serial: Serial number of the output scale.
        encoder_in_scale_diameter_m: Input scale's graduation diameter [m] (0: not stated).
        encoder_out_scale_diameter_m: Output scale's graduation diameter [m].
        encoder_in_scale_eccentricity_m: Stated mounting eccentricity of the input scale
            (run-out / 2) [m] (0: not stated).
        encoder_out_scale_eccentricity_m: The same for the output scale.
        encoder_in_scale_index_rad: The input scale turned on its shaft from its reference
            mounting [rad] (reversal).
        encoder_out_scale_index_rad: The same for the output scale.
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
    encoder_in_head_angles_rad: tuple[float, ...] = ()
    encoder_out_head_angles_rad: tuple[float, ...] = ()
    encoder_in_scale_serial: str = ''
    encoder_out_scale_serial: str = ''
    encoder_in_scale_diameter_m: float = 0.0
    encoder_out_scale_diameter_m: float = 0.0
    encoder_in_scale_eccentricity_m: float = 0.0
    encoder_out_scale_eccentricity_m: float = 0.0
    encoder_in_scale_index_rad: float = 0.0
    encoder_out_scale_index_rad: float = 0.0

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The message's fields without the header, in message order."""
        return tuple(f.name for f in fields(cls))

    @classmethod
    def from_message(cls, msg: object) -> BenchInfoData:
        """The record of a ``BenchInfo`` message (rclpy or rosbags) or anything alike.

        Args:
            msg: An object with every field of the record as an attribute (arrays as any
                sequence: ``array.array``, numpy, list); a message of the definition before
                issue 36 lacks the scale and head fields, which then keep their defaults
                ("not stated").

        Raises:
            AttributeError: A field of the older definition is missing.
            TypeError, ValueError: A value does not convert (a number that is no number).
        """
        values = {}
        for f in fields(cls):
            if f.name in _ADDED_FIELDS and not hasattr(msg, f.name):
                continue
            values[f.name] = _FIELD_TYPES[str(f.type)](getattr(msg, f.name))
        return cls(**values)

    def message_values(self) -> dict[str, Any]:
        """The fields as the message takes them: ``str``, ``float``, ``int``, lists."""
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v)
                for f in fields(self)}
