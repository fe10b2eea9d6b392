"""The bench's loss channels in a bag (issue 38): ``bench/channels`` (``BenchChannels``, one
per EncoderBlock with its seq: the input-shaft torque and the case temperature, sampled on
the encoders' clock), read without rclpy and laid onto the encoder samples.

A block whose BenchChannels is missing (lost, or the bench had no such channel for it)
gets NaN for its samples: a step reading them is then not judged, never judged from
another block's values.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import bag_topics, iter_messages
from rv_te_bench.io.msgdefs import BENCH_CHANNELS, rv_te_typestore

if TYPE_CHECKING:
    from collections.abc import Sequence

__all__ = ['ChannelSamples', 'channels_topic', 'read_bench_channels']


class ChannelSamples:
    """The loss channels on the encoder samples (NaN where a block had none).

    Attributes:
        torque_in_nm, temp_case_degc: Per sample, or None when no block had the channel.
        what: One line: where they came from, how many blocks lacked them.
    """

    __slots__ = ('temp_case_degc', 'torque_in_nm', 'what')

    def __init__(self, torque_in_nm: np.ndarray | None, temp_case_degc: np.ndarray | None,
                 what: str) -> None:
        """Hold the arrays and the description."""
        self.torque_in_nm = torque_in_nm
        self.temp_case_degc = temp_case_degc
        self.what = what


def channels_topic(path: str | Path) -> str | None:
    """The bag's BenchChannels topic (None: none; BagError: several)."""
    topics = [t for t, v in bag_topics(path).items() if v.get('type') == BENCH_CHANNELS]
    if len(topics) > 1:
        msg = f'{path}: several BenchChannels topics {sorted(topics)}'
        raise BagError(msg)
    return topics[0] if topics else None


def read_bench_channels(path: str | Path, seqs: Sequence[int], sizes: Sequence[int],
                        ) -> ChannelSamples:
    """The channels of the blocks ``seqs`` (in the order read, ``sizes`` samples each),
    concatenated like their samples.

    Raises:
        BagError: Unreadable bag or several BenchChannels topics.
    """
    topic = channels_topic(path)
    if topic is None:
        return ChannelSamples(None, None, 'none: the bag has no bench/channels (BenchChannels)')
    store = rv_te_typestore()
    by_seq: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    for _topic, msgtype, _t, data in iter_messages(Path(path), [topic]):
        if msgtype != BENCH_CHANNELS:
            continue
        m: Any = store.deserialize_cdr(bytes(data), msgtype)
        by_seq[int(m.seq)] = (np.asarray(m.torque_in_nm, dtype=np.float64),
                              np.asarray(m.temp_case_degc, dtype=np.float64))
    total = int(np.sum(sizes)) if len(sizes) else 0
    out = [np.full(total, np.nan), np.full(total, np.nan)]
    have = [False, False]
    missing = 0
    at = 0
    for seq, n in zip(seqs, sizes, strict=True):
        got = by_seq.get(int(seq))
        if got is None:
            missing += 1
        else:
            for j in (0, 1):
                if got[j].size == n:
                    out[j][at:at + n] = got[j]
                    have[j] = True
        at += n
    what = f'topic {topic} (BenchChannels, {len(by_seq)} messages'
    what += f', {missing} block(s) without)' if missing else ')'
    return ChannelSamples(out[0] if have[0] else None, out[1] if have[1] else None, what)
