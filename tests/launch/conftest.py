"""Shared helpers of the launch tests."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from pathlib import Path


def read_decoded(bag: Path, topics: list[str]) -> list[tuple[str, int, object]]:
    """(topic, log time [ns], decoded message) of ``topics``, read with mcap + mcap_ros2."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = []
    files = sorted(bag.glob('*.mcap'))
    assert files
    for f in files:
        with f.open('rb') as stream:
            reader = make_reader(stream, decoder_factories=[DecoderFactory()])
            for _s, channel, message, msg in reader.iter_decoded_messages(topics=topics):
                out.append((channel.topic, message.log_time, msg))
    return out
