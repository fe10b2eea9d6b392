"""Which bags a fleet run hashes whole to tell copies apart (issue 41: the run's fixed cost).

Bags of one bench and length have one size; hashing every one of them read all of them
before the first was analysed (0.6 CPU s for 100 bags of 7.6 MB). A cheap probe (each
file's first and last 64 kB) tells two recordings apart; only bags whose probes match are
hashed whole, and those decide.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from rv_te_bench.fleet import _run
from rv_te_bench.store import bag_fingerprint, open_store
from rv_te_bench.store.records import PROBE_BYTES


def _bag(path: Path, data: bytes) -> Path:
    path.mkdir(parents=True)
    (path / 'metadata.yaml').write_text('rosbag2_bagfile_information: {version: 9}\n')
    (path / 'rec_0.mcap').write_bytes(data)     # one file name: only the bytes differ
    return path


def test_only_bags_that_probe_alike_are_hashed_and_copies_still_found(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    rng = np.random.default_rng(41)
    size = 5 * PROBE_BYTES
    a = rng.bytes(size)
    mid = bytearray(a)
    mid[size // 2] ^= 0xFF                  # same first and last 64 kB as a, not the same bag
    paths = [_bag(tmp_path / 'a', a), _bag(tmp_path / 'b', rng.bytes(size)),
             _bag(tmp_path / 'c', rng.bytes(size)), _bag(tmp_path / 'mid', bytes(mid))]
    copy = tmp_path / 'x' / 'a'
    shutil.copytree(paths[0], copy)
    bags = [*paths, copy]
    hashed: list[Path] = []

    def counting(bag: Path) -> tuple[str, int, int]:
        hashed.append(bag)
        return bag_fingerprint(bag)

    monkeypatch.setattr(_run, 'bag_fingerprint', counting)
    with open_store(tmp_path / 'r.sqlite') as st:
        todo, skipped, duplicates = _run._todo(bags, st, force=False)
    assert sorted(hashed) == sorted([paths[0], paths[3], copy])
    assert todo == paths                      # the copy is not analysed again
    assert skipped == 0
    assert duplicates == [[str(paths[0]), str(copy)]]
