"""The parameters of the recorder: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.recorder`.
No rclpy here: the launcher checks parameter files against :data:`PARAMS` before any node
starts (:mod:`rv_te_bench.launch.node_specs`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.io.files import folder_name_problem
from rv_te_bench.params import param, param_specs

__all__ = ['DEFAULT_TOPICS', 'PARAMS', 'RecorderParams']


#: What a session records when the recorder is given no topics.
DEFAULT_TOPICS = (
    'bench/encoders', 'bench/channels', 'bench/info', 'te/samples', 'te/plot',
    'te/statistics', 'te/spectrum', 'compensation/advice', 'test/step', 'test/report',
    '/diagnostics', '/clock',
    'te/encoder_heads',
)


@dataclass(frozen=True)
class RecorderParams:
    """The recorder's parameters (bag folder, topics, chunks, splits, full-disk buffer).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    output_dir: str = param('out/bags', 'Folder in which the bag folder is created [path]')
    bag_name: str = param(
        '', 'Bag folder name inside output_dir; empty: rv_te_<UTC time>, made unique [-]',
        rule=lambda v: folder_name_problem(v) if v else None)
    topics: tuple[str, ...] = param(
        tuple(DEFAULT_TOPICS), 'Topics to record; relative names resolve under the namespace [-]')
    topic_types: tuple[str, ...] = param(
        (), "Explicit types 'topic=pkg/msg/Type'; others come from the graph [-]")
    compression: str = param('zstd', 'MCAP chunk compression [-]', choices=('zstd', 'lz4', 'none'))
    chunk_size_bytes: int = param(
        1 << 20, 'Uncompressed chunk size that triggers a write [bytes]', min_value=1024,
        max_value=1 << 30)
    flush_interval_s: float = param(
        1.0, 'Longest time a message stays in memory; bounds loss on a crash [s]', min_value=0.01,
        max_value=60.0)
    split_size_bytes: int = param(
        0, 'Start a new .mcap file past this size; 0: never [bytes]', min_value=0,
        max_value=1 << 62)
    split_duration_s: float = param(
        0.0, 'Start a new .mcap file after this span; 0: never [s]', min_value=0.0, max_value=1e7)
    duration_s: float = param(
        0.0, 'Stop and close the bag after this time; 0: until stopped [s]', min_value=0.0,
        max_value=1e7)
    discovery_period_s: float = param(
        0.5, 'Period of the graph scan for new publishers [s]', min_value=0.05, max_value=60.0)
    session_metadata_yaml: str = param(
        '', "YAML mapping stored as the bag's rv_te_session metadata record [-]")
    stall_buffer_bytes: int = param(
        64 << 20,
        'Messages held in memory while the disk is full; beyond it they are lost '
        '(counted) [bytes]',
        min_value=0, max_value=1 << 40)
    summary_file: str = param(
        '',
        'Write the closing summary (bag, messages on disk, lost) as YAML here; '
        'empty: none [path]')


PARAMS = param_specs(RecorderParams)
