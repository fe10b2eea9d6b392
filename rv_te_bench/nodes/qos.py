"""QoS profiles of the suite, by purpose (STYLE.md section 7). Every node imports these.

| profile         | policy                                  | used for                       |
|-----------------|-----------------------------------------|--------------------------------|
| ENCODER_QOS     | reliable, keep last 1000, volatile      | bench/encoders (every sample)  |
| LATCHED_QOS     | reliable, keep last 1, transient local  | bench/info, te/statistics, ... |
| PREVIEW_QOS     | sensor data: best effort, keep last 5   | live plots, previews           |
| DIAGNOSTICS_QOS | reliable, keep last 10, volatile        | /diagnostics                   |
| CLOCK_QOS       | best effort, keep last 1 (ClockQoS)     | /clock                         |

The encoder depth (1000 messages = 10 s at 100 blocks/s) covers the largest burst a
subscriber can fall behind by on a loaded 2-core machine; depth 10 drops bursts (DESIGN.md).
"""

from __future__ import annotations

from rclpy.qos import (
    DurabilityPolicy,
    HistoryPolicy,
    QoSProfile,
    ReliabilityPolicy,
    qos_profile_sensor_data,
)

__all__ = [
    'CLOCK_QOS',
    'DIAGNOSTICS_QOS',
    'ENCODER_QOS',
    'ENCODER_QUEUE_DEPTH',
    'LATCHED_QOS',
    'PREVIEW_QOS',
]

ENCODER_QUEUE_DEPTH = 1000
LATCHED_DEPTH = 20

ENCODER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=ENCODER_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

LATCHED_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    # not 1: a burst (two windows, or two advice methods finishing together) must not
    # overwrite itself, and a late joiner gets every advice method, not only the last
    depth=LATCHED_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

PREVIEW_QOS = QoSProfile(
    history=qos_profile_sensor_data.history,
    depth=qos_profile_sensor_data.depth,
    reliability=qos_profile_sensor_data.reliability,
    durability=qos_profile_sensor_data.durability,
)

DIAGNOSTICS_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

CLOCK_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=1,
    reliability=ReliabilityPolicy.BEST_EFFORT,
    durability=DurabilityPolicy.VOLATILE,
)
