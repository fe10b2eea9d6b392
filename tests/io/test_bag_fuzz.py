"""Fuzz the reader: truncations and bit flips of a small real bag raise only BagError, and
the non-strict reader never raises while scanning (damage is reported as partial)."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import (
    bag_summary,
    decode_encoder_block,
    iter_messages,
    read_bench_info,
    read_encoder_blocks,
)
from tests.io.bag_fixtures import encoder_cdr, write_sample_bag


@pytest.fixture(scope='module')
def templates(tmp_path_factory: pytest.TempPathFactory) -> dict[str, tuple[Path, bytes]]:
    """A small real bag per compression (6 blocks of 20 samples, 1 KiB chunks)."""
    root = tmp_path_factory.mktemp('fuzz_templates')
    out = {}
    for compression in ('none', 'zstd', 'lz4'):
        bag = root / compression
        write_sample_bag(bag, n_blocks=6, block=20, compression=compression,
                         chunk_size_bytes=1024)
        (file,) = bag.glob('*.mcap')
        out[compression] = (bag, file.read_bytes())
    return out


def _read_everything(bag: Path) -> None:
    """Every public reader, strict; only BagError may escape."""
    for call in (lambda: list(read_encoder_blocks(bag)),
                 lambda: [bytes(m[3]) for m in iter_messages(bag)],
                 lambda: bag_summary(bag),
                 lambda: read_bench_info(bag)):
        try:
            call()
        except BagError:
            pass


@pytest.fixture(scope='module')
def scratch(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp('fuzz_scratch')


@given(compression=st.sampled_from(['none', 'zstd', 'lz4']),
       cut=st.floats(0.0, 1.0),
       flips=st.lists(st.tuples(st.floats(0.0, 1.0), st.integers(0, 7)), max_size=4))
def test_damaged_bag_raises_only_bag_error(templates: dict, scratch: Path, compression: str,
                                           cut: float, flips: list[tuple[float, int]]) -> None:
    bag, data = templates[compression]
    damaged = bytearray(data[: int(len(data) * cut) if cut < 0.999 else len(data)])
    for pos, bit in flips:
        if damaged:
            damaged[min(int(pos * len(damaged)), len(damaged) - 1)] ^= 1 << bit
    target = scratch / 'bag'
    shutil.rmtree(target, ignore_errors=True)
    shutil.copytree(bag, target)
    (file,) = target.glob('*.mcap')
    file.write_bytes(bytes(damaged))
    _read_everything(target)
    try:
        stream = read_encoder_blocks(target, strict=False)
    except BagError:
        return  # layout refused up front (empty file, bad magic)
    blocks = list(stream)
    if bytes(damaged) == data:
        assert len(blocks) == 6
        assert not stream.partial


@given(data=st.binary(max_size=300), flips=st.lists(st.integers(0, 10_000), max_size=6))
def test_decode_of_damaged_cdr_raises_only_bag_error(data: bytes, flips: list[int]) -> None:
    raw = bytearray(data or encoder_cdr(1, 5))
    for f in flips:
        raw[f % len(raw)] ^= 1 << (f % 8)
    try:
        block = decode_encoder_block(bytes(raw))
    except BagError:
        return
    # Whatever decoded must be internally consistent with the bytes it came from.
    for arr in (block.time_offset_s, block.theta_in_rad, block.theta_out_rad):
        assert arr.nbytes <= len(raw)
