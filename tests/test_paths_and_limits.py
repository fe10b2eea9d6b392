"""Paths and limits (issue #16): names that would leave their output folder are refused with
one line, default names never collide, report files are written all or nothing (a full disk
leaves no 0-byte PNG)."""

from __future__ import annotations

import datetime as dt
import errno
import os
from pathlib import Path

import pytest

from rv_te_bench.cli.main import main
from rv_te_bench.errors import ParameterFileError, RvTeError
from rv_te_bench.io import files as files_mod
from rv_te_bench.io.files import claim_folder, folder_name_problem, write_all
from tests.io.faults import tmpfs

pytestmark = pytest.mark.timeout(120)


def _one_error_line(err: str) -> str:
    lines = [ln for ln in err.strip().splitlines() if ln.startswith('ERROR:')]
    assert len(lines) == 1, err
    return lines[0]


def _tree(folder: Path) -> set[str]:
    return {str(p.relative_to(folder)) for p in folder.rglob('*')}


@pytest.mark.parametrize(('argv', 'flag', 'bad'), [
    (['record', '--name', '../x'], '--name', "'../x'"),
    (['record', '--name', 'a/b'], '--name', "'a/b'"),
    (['record', '--name', '..'], '--name', "'..'"),
    (['demo', '--session', '../../x'], '--session', "'../../x'"),
    (['demo', '--session', '/tmp/abs'], '--session', "'/tmp/abs'"),
])
def test_names_that_leave_the_output_folder_are_refused(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str],
        argv: list[str], flag: str, bad: str) -> None:
    work = tmp_path / 'a' / 'b'
    work.mkdir(parents=True)
    monkeypatch.chdir(work)
    out = ['--out', 'out'] if argv[0] == 'record' else ['--out-dir', 'out']
    got = main([*argv, *out])
    line = _one_error_line(capsys.readouterr().err)
    assert got == 2
    assert line.startswith(f'ERROR: {flag} must be a plain folder name inside the output '
                           'folder')
    assert bad in line
    assert _tree(tmp_path) == {'a', 'a/b'}           # nothing created anywhere


def test_long_name_is_shown_shortened() -> None:
    problem = folder_name_problem('../' + 'x' * 5000)
    assert problem is not None
    assert len(problem) < 200
    assert '5003 characters' in problem


def test_launch_refuses_a_recorder_bag_name_outside_its_folder() -> None:
    from rv_te_bench.launch.session import build_session

    with pytest.raises(ParameterFileError, match=r"'bag_name' must be a plain folder name"):
        build_session([], overrides=['recorder.bag_name=../../x'])


def test_claim_folder_numbers_default_names_and_refuses_given_ones(tmp_path: Path) -> None:
    first = claim_folder(tmp_path, 'run', numbered=True)
    second = claim_folder(tmp_path, 'run', numbered=True)
    assert (first.name, second.name) == ('run', 'run-2')
    with pytest.raises(FileExistsError):
        claim_folder(tmp_path, 'run', numbered=False)


@pytest.mark.ros
def test_two_default_named_recorders_in_the_same_second_get_two_bags(
        ros_context: object, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip('rclpy')
    from types import SimpleNamespace

    from rclpy.parameter import Parameter

    from rv_te_bench.nodes import recorder as recorder_mod
    from rv_te_bench.nodes.recorder import RecorderNode

    now = dt.datetime.now(dt.UTC)

    class _SameSecond(dt.datetime):
        """The recorders' clock stands still: both start in this second, however long the
        nodes take to build on a busy machine (it took > 2 s under load and the test
        failed on the clock, not on the recorder)."""

        @classmethod
        def now(cls, tz: dt.tzinfo | None = None) -> dt.datetime:  # type: ignore[override]
            return now.astimezone(tz)

    monkeypatch.setattr(recorder_mod, 'dt', SimpleNamespace(datetime=_SameSecond, UTC=dt.UTC))
    # the default names of this second and the next are taken (by another recorder that
    # started in the same second): the recorder must not fail, nor write into them
    taken = {f'rv_te_{(now + dt.timedelta(seconds=s)).strftime("%Y%m%d_%H%M%S")}'
             for s in (0, 1)}
    for name in taken:
        (tmp_path / name).mkdir()
    params = [Parameter('output_dir', value=str(tmp_path)), Parameter('topics', value=['x'])]
    nodes = [RecorderNode(node_name=f'rec{k}', context=ros_context,
                          parameter_overrides=params) for k in range(2)]
    try:
        paths = [n.bag_path for n in nodes]
    finally:
        for n in nodes:
            n.destroy_node()
    assert len(set(paths)) == 2
    assert all(p.parent == tmp_path and p.name not in taken for p in paths)
    assert all(p.name.rsplit('_', 1)[0] in taken for p in paths)   # <default>_<n>
    assert all((p / 'metadata.yaml').is_file() for p in paths)
    assert all(not any((tmp_path / t).iterdir()) for t in taken)


# ---------------------------------------------------------------- reports on a full disk
def _enospc_after(monkeypatch: pytest.MonkeyPatch, budget: int) -> None:
    """Make io.files' writes fail with ENOSPC once ``budget`` bytes were written."""
    real_write = os.write
    left = {'n': budget}

    def write(fd: int, data: bytes | memoryview) -> int:
        if left['n'] <= 0:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        n = real_write(fd, bytes(data)[:left['n']])
        left['n'] -= n
        return n

    monkeypatch.setattr(files_mod.os, 'write', write)


def test_write_all_is_all_or_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / 'a.png').write_bytes(b'old a')
    _enospc_after(monkeypatch, 1500)
    with pytest.raises(OSError, match='No space left') as info:
        write_all({tmp_path / 'a.png': b'A' * 1000, tmp_path / 'b.png': b'B' * 1000})
    assert info.value.filename == str(tmp_path / 'b.png')
    assert sorted(p.name for p in tmp_path.iterdir()) == ['a.png']   # no temporary left
    assert (tmp_path / 'a.png').read_bytes() == b'old a'


@pytest.fixture(scope='module')
def analysis() -> object:
    from rv_te_bench.report.analysis import analyze_bag

    return analyze_bag(Path(__file__).resolve().parents[1] / 'bags' / 'sample')


def test_report_on_a_full_disk_leaves_no_partial_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch, analysis: object) -> None:
    from rv_te_bench.report.html import write_report

    good = write_report([analysis], tmp_path / 'report')
    before = {p.name: p.read_bytes() for p in good}
    # the first image fits, the second does not
    _enospc_after(monkeypatch, len(before['te.png']) + 10)
    with pytest.raises(RvTeError, match=r'Cannot write report into .*: spectrum\.png: No '
                                        r'space left on device \(no report file was written'):
        write_report([analysis], tmp_path / 'report', force=True)
    assert {p.name: p.read_bytes() for p in (tmp_path / 'report').iterdir()} == before


def test_report_on_a_full_tmpfs(tmp_path: Path, analysis: object,
                                capsys: pytest.CaptureFixture[str]) -> None:
    sample = Path(__file__).resolve().parents[1] / 'bags' / 'sample'
    with tmpfs(tmp_path / 'mnt', 64 << 10) as mnt:
        got = main(['analyze', str(sample), '--no-db', '--report', str(mnt / 'report')])
        line = _one_error_line(capsys.readouterr().err)
        assert got == 1
        assert 'No space left on device' in line
        assert list(mnt.iterdir()) == []        # no 0-byte (or cut) PNG, no temporary


def test_model_csv_and_plot_on_a_full_disk_leave_no_cut_file(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    argv = ['model', 'wang2020-2kv', '--revolutions', '0.05']
    assert main([*argv, '--csv', str(tmp_path / 'ok.csv'), '--plot', str(tmp_path / 'ok.png')]) == 0
    csv_size = (tmp_path / 'ok.csv').stat().st_size
    capsys.readouterr()
    _enospc_after(monkeypatch, csv_size // 2)
    got = main([*argv, '--csv', str(tmp_path / 'te.csv')])
    assert got == 1
    assert 'No space left on device' in _one_error_line(capsys.readouterr().err)
    _enospc_after(monkeypatch, 1000)
    got = main([*argv, '--plot', str(tmp_path / 'te.png')])
    assert got == 1
    assert 'No space left on device' in _one_error_line(capsys.readouterr().err)
    assert sorted(p.name for p in tmp_path.iterdir()) == ['ok.csv', 'ok.png']
