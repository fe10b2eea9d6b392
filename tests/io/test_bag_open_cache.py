"""metadata.yaml and BenchInfo's parameters_yaml are parsed once per content (issue 41).

An analysis opens its bag five times and reads the bench's parameters three times; each
parse costs ~1 ms. The parsed documents are kept by content: a file rewritten (even to
the same size, within the file system's time stamp granularity) is parsed again, and each
caller gets a copy of its own.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from rv_te_bench.io import _bag_open, bench_record
from rv_te_bench.io.bag_reader import open_bag, read_bench_info
from tests.io.bag_fixtures import write_sample_bag


@pytest.fixture
def parses(monkeypatch: pytest.MonkeyPatch) -> list[str]:
    seen: list[str] = []
    real_meta, real_params = _bag_open.load_yaml, bench_record.load_yaml

    def meta(*args: object, **kwargs: object) -> object:
        seen.append('metadata')
        return real_meta(*args, **kwargs)

    def params(*args: object, **kwargs: object) -> object:
        seen.append('parameters')
        return real_params(*args, **kwargs)

    monkeypatch.setattr(_bag_open, 'load_yaml', meta)
    monkeypatch.setattr(bench_record, 'load_yaml', params)
    _bag_open._parsed_metadata.cache_clear()
    bench_record._parsed_parameters.cache_clear()
    return seen


def test_metadata_is_parsed_once_per_content(tmp_path: Path, parses: list[str]) -> None:
    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=4)
    first = open_bag(bag)
    first.info['storage_identifier'] = 'changed by a caller'
    first.info['relative_file_paths'].append('nothing.mcap')
    again = open_bag(bag)
    assert parses.count('metadata') == 1
    assert again.info['storage_identifier'] == 'mcap'       # a copy of its own
    assert 'nothing.mcap' not in again.info['relative_file_paths']
    # rewritten in place to the same size at once: parsed again, the new content read
    meta = bag / 'metadata.yaml'
    text = meta.read_text()
    assert 'duration:' in text
    meta.write_text(text.replace('duration:', 'duratioN:'))   # an unknown key, same size
    assert meta.stat().st_size == len(text.encode())
    third = open_bag(bag)
    assert parses.count('metadata') == 2
    assert 'duratioN' in third.info and 'duration' not in third.info


def test_a_bad_metadata_file_is_still_refused(tmp_path: Path) -> None:
    from rv_te_bench.errors import BagError

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=2)
    open_bag(bag)
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information: [unclosed\n')
    with pytest.raises(BagError, match='metadata'):
        open_bag(bag)


def test_parameters_yaml_is_parsed_once(tmp_path: Path, parses: list[str]) -> None:
    from rv_te_bench.io.bench_record import bench_uncertainty_of, encoder_zero_of

    bag = tmp_path / 'bag'
    write_sample_bag(bag, n_blocks=2)
    info = read_bench_info(bag)
    assert info is not None and info.parameters_yaml
    zero = encoder_zero_of(info)
    model = bench_uncertainty_of(info)
    assert encoder_zero_of(info) == zero and bench_uncertainty_of(info) == model
    assert parses.count('parameters') == 1
    record = bench_record._parameters_record(info.parameters_yaml)
    record.clear()                                   # a caller's copy
    assert bench_record._parameters_record(info.parameters_yaml)
