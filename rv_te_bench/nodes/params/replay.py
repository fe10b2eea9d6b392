"""The parameters of the replay node: one frozen record, declared from its fields.

The node is :mod:`rv_te_bench.nodes.replay`; ``rv-te replay`` checks its flags against the
same ranges. No rclpy here.
"""

from __future__ import annotations

from dataclasses import dataclass

from rv_te_bench.params import param, param_specs

__all__ = ['PARAMS', 'RATE_RANGE', 'START_OFFSET_RANGE_S', 'WAIT_RANGE_S', 'ReplayParams']

#: Playback speed factors accepted [-].
RATE_RANGE = (0.001, 1000.0)
#: Skips from the bag's start accepted [s].
START_OFFSET_RANGE_S = (0.0, 1e7)
#: Waits for subscribers accepted [s].
WAIT_RANGE_S = (0.0, 3600.0)


@dataclass(frozen=True)
class ReplayParams:
    """The replay node's parameters (all read-only).

    Declared from these fields (:func:`~rv_te_bench.params.param_specs`), read through the
    record (:func:`~rv_te_bench.params.params_record`); units in the descriptions.
    """

    bag: str = param('', 'Bag folder (or .mcap file) to play [path]')
    rate: float = param(1.0, 'Playback speed factor; 2 plays twice as fast [-]',
                        min_value=RATE_RANGE[0], max_value=RATE_RANGE[1])
    loop: bool = param(False, 'Start again at the end [-]')
    topics: tuple[str, ...] = param((), 'Topics to play; empty: all [-]')
    start_offset_s: float = param(0.0, 'Skip this much of the bag from its start [s]',
                                  min_value=START_OFFSET_RANGE_S[0],
                                  max_value=START_OFFSET_RANGE_S[1])
    clock: bool = param(False, 'Publish the playback time on /clock [-]')
    clock_rate_hz: float = param(100.0, 'Rate of /clock messages [Hz]', min_value=1.0,
                                 max_value=10_000.0)
    wait_for_subscribers_s: float = param(
        0.0, 'Wait up to this long for a subscriber on every topic before playing [s]',
        min_value=WAIT_RANGE_S[0], max_value=WAIT_RANGE_S[1])


PARAMS = param_specs(ReplayParams)
