"""The middleware settings of rv-te-bench's node processes (no rclpy import here).

Fast DDS (ROS 2 Jazzy's default middleware) sends a reliable writer's heartbeat every 3 s,
and a reader in another process acknowledges a sample only when a heartbeat asks: a
``wait_for_all_acked`` across processes returned after 2.7-3.0 s although the sample
arrived at once (measured here). The nodes wait for acknowledgements where it matters
(the sequencer's zero setpoint when it stops, a finished bench's last blocks, the
recorder's 'closed' status), so each such wait ran into its timeout: 2 s of every stop of a
session with a test_sequencer. :func:`use_quick_acknowledgements` points Fast DDS at
:data:`PROFILE` (heartbeats every 100 ms while something is unacknowledged: the same
waits take ~0.1 s, and a lost sample is repaired as soon; and a participant lease of 6 s
renewed every second instead of 20 s / 3 s: a node process killed without a word leaves the
others' graph within ~6 s) before the process makes its first participant. A profile file
the user chose (``FASTRTPS_DEFAULT_PROFILES_FILE`` / ``FASTDDS_DEFAULT_PROFILES_FILE``),
another middleware (``RMW_IMPLEMENTATION``) or QoS taken from XML
(``RMW_FASTRTPS_USE_QOS_FROM_XML``: the profile would then replace the nodes' QoS) is left
alone.

A paced (real-time) bench's process gets :data:`PACED_PROFILE` instead
(:func:`use_paced_transport`, set by the launcher): the same settings over UDPv4 only. Over
shared memory its SCHED_FIFO thread waited in ``publish()`` for the interprocess mutex of a
reader's port, held by ordinary threads of other processes (the profile file says more).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from collections.abc import MutableMapping

__all__ = ['PACED_PROFILE', 'PROFILE', 'PROFILE_ENV', 'use_paced_transport',
           'use_quick_acknowledgements']

#: The Fast DDS XML profile (the default data writer's heartbeat period).
PROFILE = Path(__file__).with_name('fastdds_profile.xml')
#: :data:`PROFILE` with UDPv4 as the only transport, for a paced bench's process.
PACED_PROFILE = Path(__file__).with_name('fastdds_profile_paced.xml')
#: The variables Fast DDS reads its profile file from (2.x, 3.x).
PROFILE_ENV = ('FASTRTPS_DEFAULT_PROFILES_FILE', 'FASTDDS_DEFAULT_PROFILES_FILE')
_FAST_DDS = ('', 'rmw_fastrtps_cpp', 'rmw_fastrtps_dynamic_cpp')


def use_quick_acknowledgements(env: MutableMapping[str, str]) -> bool:
    """Set ``env``'s Fast DDS profile file to :data:`PROFILE` unless the user set one or
    another middleware is chosen; True when set. Takes effect for participants made after
    it (call it before ``rclpy.init``)."""
    return _use_profile(env, PROFILE)


def use_paced_transport(env: MutableMapping[str, str]) -> bool:
    """Give a paced bench's node process :data:`PACED_PROFILE` (:data:`PROFILE`'s
    settings, UDPv4 on the loopback interface only, no shared memory); True when set.

    Only where the session keeps to this machine (``ROS_AUTOMATIC_DISCOVERY_RANGE`` is
    ``LOCALHOST``, the launcher's default): rmw_fastrtps then sets up the transports itself
    (UDP on 127.0.0.1 and shared memory) over any profile, so the range becomes
    ``SYSTEM_DEFAULT`` (the profile's transports are used as they are), and the profile's
    127.0.0.1 keeps the process on this machine as ``LOCALHOST`` did. Another range, a
    profile the user set, or another middleware: nothing changes (False).
    """
    if env.get('ROS_AUTOMATIC_DISCOVERY_RANGE') != 'LOCALHOST' \
            or not _use_profile(env, PACED_PROFILE):
        return False
    env['ROS_AUTOMATIC_DISCOVERY_RANGE'] = 'SYSTEM_DEFAULT'
    return True


def _use_profile(env: MutableMapping[str, str], profile: Path) -> bool:
    if any(env.get(v) for v in PROFILE_ENV) or \
            env.get('RMW_IMPLEMENTATION', '') not in _FAST_DDS or not profile.is_file() or \
            env.get('RMW_FASTRTPS_USE_QOS_FROM_XML', '') not in ('', '0'):
        return False
    env[PROFILE_ENV[0]] = str(profile)
    return True
