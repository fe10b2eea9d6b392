"""Sessions in one process (`--single-process`, `rv-te bench`): nodes start, run, end."""

from __future__ import annotations

import pytest

pytestmark = pytest.mark.ros

pytest.importorskip('rclpy')

from rv_te_bench.cli.main import main  # noqa: E402


def test_bench_alone_runs_its_duration(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(['bench', '--param', 'time_mode=fast', '--param', 'speed_factor=0.0',
                 '--param', 'duration_s=0.5', '--param', 'speed_rpm=3000.0'])
    assert code == 0, capsys.readouterr().err


def test_single_process_session_with_te_node(capsys: pytest.CaptureFixture[str]) -> None:
    code = main(['launch', '--default', '--single-process', '--nodes', 'bench,te_node',
                 '--param', 'bench.duration_output_revs=1.0',
                 '--param', 'bench.speed_rpm=3000.0', '--param', 'bench.speed_factor=0.0'])
    assert code == 0, capsys.readouterr().err


def test_single_process_bad_parameter_is_one_error_line(
        capsys: pytest.CaptureFixture[str]) -> None:
    # passes the file check (a string) but the bench rejects the preset at start-up
    code = main(['bench', '--param', 'preset=no-such-reducer'])
    err = capsys.readouterr().err
    assert code == 1
    assert "unknown preset 'no-such-reducer'" in err
    assert 'Traceback' not in err
