"""QoS profiles of the suite, by purpose (STYLE.md section 7). Every node imports these.

| profile         | policy                                  | used for                       |
|-----------------|-----------------------------------------|--------------------------------|
| ENCODER_QOS     | reliable, keep last 1000, volatile      | bench/encoders (every sample)  |
| JOINT_STATE_QOS | reliable, keep last 5000, volatile      | joint_states (one sample each) |
| TE_SAMPLES_QOS  | reliable, keep last 1000, transient local | te/samples (decimated TE)    |
| LATCHED_QOS     | reliable, keep last 1, transient local  | bench/info, te/statistics, ... |
| PREVIEW_QOS     | sensor data: best effort, keep last 5   | live plots, previews           |
| DIAGNOSTICS_QOS | reliable, keep last 10, volatile        | /diagnostics                   |
| CLOCK_QOS       | best effort, keep last 1 (ClockQoS)     | /clock                         |
| COMMAND_QOS     | reliable, keep last 10, volatile        | .../commands setpoints         |

Setpoints to a ros2_control bench go to ``forward_command_controller``'s ``~/commands``,
which subscribes with ``rclcpp::SystemDefaultsQoS()`` (reliable, volatile, keep last 10):
COMMAND_QOS is that, so the sequencer's publishers match a real controller.

The encoder depth (1000 messages = 10 s at 100 blocks/s) covers the largest burst a
subscriber can fall behind by on a loaded 2-core machine; depth 10 drops bursts (DESIGN.md).

joint_states carries one sample per message (ros2_control's joint_state_broadcaster), so its
queue is deep: 5000 messages (5 s at 1 kHz). Not more: Fast DDS's default resource limits
(``max_samples`` 5000 per reader and writer) cap the history whatever the depth, and a
KEEP_LAST depth above that cap loses the *newest* messages of a longer backlog (the reader
is "full" and refuses them) where one at the cap loses the *oldest* (KEEP_LAST replaces
them). Measured with rmw_fastrtps_cpp 8.4 (tests/nodes/test_qos.py): 7400 messages queued
with depth 10000 -> the first 5000 arrive and the last 2400 never do, so a stream's end
vanishes with no stamp jump to show it; with depth 5000 -> the last 5000 arrive, and the
adapter reports the missing start as a gap. The simulated bench keeps one tick's burst of
JointStates within this depth (bench_node's catch-up bound).

te/samples keeps its last 1000 messages for late joiners: the session's recorder may
discover the TE node's publisher seconds after it started (DDS participants that miss each
other's first announcements meet at the next one, ~3 s later), and a fast session is over
by then; with this history the recording still starts at the first decimated sample.
Volatile subscribers (live plots) are compatible and get no history.
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
    'COMMAND_QOS',
    'DIAGNOSTICS_QOS',
    'ENCODER_QOS',
    'ENCODER_QUEUE_DEPTH',
    'JOINT_STATE_QOS',
    'JOINT_STATE_QUEUE_DEPTH',
    'LATCHED_QOS',
    'PREVIEW_QOS',
    'TE_SAMPLES_QOS',
]

ENCODER_QUEUE_DEPTH = 1000
LATCHED_DEPTH = 20

ENCODER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=ENCODER_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

JOINT_STATE_QUEUE_DEPTH = 5000

JOINT_STATE_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=JOINT_STATE_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)

TE_SAMPLES_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=ENCODER_QUEUE_DEPTH,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
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

COMMAND_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_LAST,
    depth=10,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)
