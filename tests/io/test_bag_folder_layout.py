"""A bag folder whose metadata.yaml and files disagree (issue #16, paths and limits): each
case is one clear line, a listed entry that is not a regular file is never opened (a FIFO
would hang the reader, /dev/zero would never end), and a .mcap that metadata.yaml does not
list is ignored with a warning (as rosbags ignores it), not merged silently."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
import yaml
from rosbags.highlevel import AnyReader

from rv_te_bench.cli.main import main
from rv_te_bench.errors import BagError
from rv_te_bench.io.bag_reader import bag_summary, open_bag, read_encoder_blocks
from tests.io.bag_fixtures import ENCODER_TOPIC, write_sample_bag

pytestmark = pytest.mark.timeout(60)


def _edit_metadata(bag: Path, **changes: object) -> None:
    meta = bag / 'metadata.yaml'
    doc = yaml.safe_load(meta.read_text())
    doc['rosbag2_bagfile_information'].update(changes)
    meta.write_text(yaml.safe_dump(doc))


@pytest.fixture
def bag(tmp_path: Path) -> Path:
    path = tmp_path / 'bag'
    write_sample_bag(path, n_blocks=30)
    return path


def _one_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    assert main(argv) == 1
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR:')]
    assert len(lines) == 1, err
    assert 'Traceback' not in err
    return lines[0]


def test_relative_file_paths_as_a_string_is_one_line(
        bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _edit_metadata(bag, relative_file_paths='bag_0.mcap')
    with pytest.raises(BagError, match=r"relative_file_paths must be a list of file names, "
                                       r"got a string: 'bag_0.mcap'"):
        open_bag(bag)
    line = _one_error(['analyze', str(bag), '--no-db'], capsys)
    assert "got a string: 'bag_0.mcap'" in line
    assert "'b', 'a', 'g'" not in line           # not character by character
    _assert_no_misleading_hint(line)
    _assert_no_misleading_hint(_one_error(['identify', str(bag)], capsys))


def _assert_no_misleading_hint(line: str) -> None:
    """A bag that cannot be read is not fixed by --ratio / --preset: no such hint, and no
    stray '.;' where a hint was glued to a sentence (issue #16)."""
    assert '--ratio' not in line and '--preset' not in line, line
    assert '.;' not in line, line


@pytest.mark.parametrize('entry', [[1, 2], ['ok.mcap', None], {'a': 1}, None])
def test_relative_file_paths_of_other_types(bag: Path, entry: object) -> None:
    _edit_metadata(bag, relative_file_paths=entry)
    with pytest.raises(BagError, match='relative_file_paths must be a list of file names'):
        open_bag(bag)


def _replace_listed_file(bag: Path, kind: str) -> Path:
    listed = bag / 'bag_0.mcap'
    listed.unlink()
    if kind == 'fifo':
        os.mkfifo(listed)
    elif kind == 'directory':
        listed.mkdir()
    elif kind == '/dev/zero':
        listed.symlink_to('/dev/zero')
    return listed


@pytest.mark.parametrize(('kind', 'what'), [
    ('fifo', 'a FIFO'), ('directory', 'a directory'),
    ('/dev/zero', 'a character device (a symlink to /dev/zero)'), ('missing', 'missing')])
def test_listed_entry_that_is_not_a_regular_file(
        bag: Path, kind: str, what: str, capsys: pytest.CaptureFixture[str]) -> None:
    _replace_listed_file(bag, kind)
    with pytest.raises(BagError, match=r'bag_0\.mcap') as info:
        open_bag(bag)
    assert what in str(info.value)
    if kind != 'missing':
        assert 'missing' not in str(info.value)
        assert 'not a regular file' in str(info.value)
    line = _one_error(['analyze', str(bag), '--no-db'], capsys)   # returns: nothing opened it
    assert what in line
    _assert_no_misleading_hint(line)
    line = _one_error(['identify', str(bag)], capsys)
    assert what in line
    _assert_no_misleading_hint(line)


@pytest.mark.parametrize('content', ['garbage', 'truncated'])
def test_a_file_that_is_no_readable_mcap_bag_says_so(
        tmp_path: Path, bag: Path, content: str, capsys: pytest.CaptureFixture[str]) -> None:
    """Garbage after the MCAP magic, or a bag cut before its first encoder message: 'not a
    readable MCAP bag', not 'the bag has no BenchInfo ... pass --ratio' (issue #21; fails
    before: the garbage was reported as a bag without BenchInfo, the truncated one as a
    damaged BenchInfo with the --ratio / --preset hints)."""
    (src,) = bag.glob('*.mcap')
    data = src.read_bytes()
    bad = tmp_path / f'{content}.mcap'
    if content == 'garbage':
        bad.write_bytes(data[:8] + b'\x00' * 500)
    else:   # cut 300 bytes in, among the schema / channel records: no message is left
        bad.write_bytes(data[:300])
    for argv in (['analyze', str(bad), '--no-db'], ['identify', str(bad)]):
        line = _one_error(argv, capsys)
        assert f'{bad} is not a readable MCAP bag' in line, line
        _assert_no_misleading_hint(line)


def test_unlisted_mcap_is_ignored_with_a_warning(
        tmp_path: Path, bag: Path, capsys: pytest.CaptureFixture[str]) -> None:
    other = tmp_path / 'other'
    write_sample_bag(other, n_blocks=5)
    shutil.copy(other / 'other_0.mcap', bag / 'stray.mcap')   # another session's file
    layout = open_bag(bag)
    assert [f.name for f in layout.files] == ['bag_0.mcap']
    assert layout.notes == ('stray.mcap is not listed in metadata.yaml: ignored',)
    assert [b.seq for b in read_encoder_blocks(bag)] == list(range(30))   # not 35
    with AnyReader([bag]) as reader:                          # rosbags agrees
        assert sum(1 for c in reader.connections if c.topic == ENCODER_TOPIC) == 1
        assert reader.message_count == 31
    assert bag_summary(bag)['topics'][ENCODER_TOPIC]['count'] == 30
    assert main(['analyze', str(bag), '--no-db']) == 0
    err = capsys.readouterr().err
    assert [ln for ln in err.splitlines() if 'stray.mcap' in ln] == [
        f'WARNING: {bag}: stray.mcap is not listed in metadata.yaml: ignored']


def test_analysis_states_what_the_recorder_could_not_write(
        tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """A bag whose disk was full for a while: `rv-te analyze` says how many messages are
    missing and when, from metadata.yaml, besides the sequence gap it finds."""
    import time

    from tests.io.conftest import FLUSH_S, block, log_ns, start_bag, write_until_stalled
    from tests.io.faults import SmallDisk

    disk = SmallDisk(1_000_000)
    bag = tmp_path / 'bag'
    writer, _ = start_bag(bag, storage=disk, stall_buffer_bytes=0)
    full_at = write_until_stalled(writer)
    for seq in range(full_at, full_at + 20):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    disk.capacity_bytes = 3_000_000
    time.sleep(2 * FLUSH_S)
    for seq in range(full_at + 20, full_at + 60):
        writer.write(ENCODER_TOPIC, log_ns(seq), block(seq))
    writer.close()
    lost = writer.lost[ENCODER_TOPIC]
    (gap,) = writer.write_gaps
    assert main(['analyze', str(bag), '--no-db', '--no-advice']) == 0
    err = capsys.readouterr().err
    assert f'WARNING: {bag}: the recorder could not write {lost} messages to this bag' in err
    assert (f'WARNING: {bag}: write gap 1: {lost} messages logged ' in err
            and '(No space left on device)' in err)
    assert f'{(gap.lost_last_ns - gap.lost_first_ns) * 1e-9:.2f} s) are missing' in err
    assert 'gap(s) in the encoder stream' in err
