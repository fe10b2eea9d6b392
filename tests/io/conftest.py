"""Shared helpers of the io tests: a bag written block by block until the disk is full
(tests/io/test_disk_full.py and tests/io/test_bag_folder_layout.py use them)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from rv_te_bench.io.bag_writer import BagWriter, qos_profile_dict
from rv_te_bench.io.msgdefs import BENCH_INFO, ENCODER_BLOCK
from tests.io.bag_fixtures import ENCODER_TOPIC, INFO_TOPIC, T0_NS, bench_info_cdr, encoder_cdr

if TYPE_CHECKING:
    from pathlib import Path

BLOCK = 100            # samples per EncoderBlock: 3,388 bytes of CDR
CHUNK = 8192           # uncompressed chunk size: 2-3 blocks per chunk
FLUSH_S = 0.02


def log_ns(seq: int) -> int:
    """The log time the test gives block ``seq`` (100 blocks/s)."""
    return T0_NS + seq * 10_000_000 + 1


_CDR: dict[int, bytes] = {}


def block(seq: int) -> bytes:
    if seq not in _CDR:
        _CDR[seq] = encoder_cdr(seq, BLOCK)
    return _CDR[seq]


def start_bag(path: Path, **kwargs: object) -> tuple[BagWriter, list[str]]:
    events: list[str] = []
    writer = BagWriter(path, compression='none', chunk_size_bytes=CHUNK,
                       flush_interval_s=FLUSH_S, session_metadata={'preset': 'wang2020-2kv'},
                       on_event=events.append, **kwargs)  # type: ignore[arg-type]
    writer.add_topic(INFO_TOPIC, BENCH_INFO, offered_qos_profiles=[
        qos_profile_dict(durability='transient_local', depth=1)])
    writer.add_topic(ENCODER_TOPIC, ENCODER_BLOCK,
                     offered_qos_profiles=[qos_profile_dict(depth=1000)])
    writer.write(INFO_TOPIC, T0_NS, bench_info_cdr())
    return writer, events


def write_until_stalled(writer: BagWriter, start: int = 0, limit: int = 5000) -> int:
    """Write blocks from ``start`` until the writer reports a full disk; the next seq."""
    seq = start
    while not writer.stalled:
        assert seq < limit, 'the disk never filled'
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
        seq += 1
    return seq
