"""rv_te_msgs_py/cmake: how the build finds ament, checked at the CMake level.

``rv_te_find_ament_prefix`` must be a no-op where a real ROS 2 install is sourced (there is
none on this machine: a fake prefix with the ament index entry a sourced /opt/ros/jazzy has
stands in for it, and the Python probe is made to fail loudly if it were consulted), and
must find the ros-jazzy wheels' prefix in a venv. ``fix_ros_wheel_imported_targets`` may drop
only the wheels' non-existent /opt/python include dirs. Runs cmake in script mode / a
LANGUAGES NONE project: a second or so, no compiler.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

CMAKE_DIR = Path(__file__).resolve().parents[2] / 'rv_te_msgs_py' / 'cmake'
CMAKE = shutil.which('cmake')
pytestmark = pytest.mark.skipif(CMAKE is None, reason='cmake not installed')


def _env(ament_prefix_path: str | None) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items()
           if k not in {'AMENT_PREFIX_PATH', '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}}
    if ament_prefix_path is not None:
        env['AMENT_PREFIX_PATH'] = ament_prefix_path
    return env


def detect(tmp_path: Path, *, python: str, ament_prefix_path: str | None = None,
           defines: dict[str, str] | None = None) -> tuple[str, str]:
    """Run the detection in cmake script mode; return (prefix or '', cmake's output)."""
    script = tmp_path / 'driver.cmake'
    script.write_text(f'include("{CMAKE_DIR / "ament_prefix.cmake"}")\n'
                      'rv_te_find_ament_prefix(p)\n'
                      'message(STATUS "RESULT=[${p}]")\n', encoding='utf-8')
    args = [CMAKE, f'-DPython3_EXECUTABLE={python}']
    args += [f'-D{k}={v}' for k, v in (defines or {}).items()]
    proc = subprocess.run([*args, '-P', str(script)], env=_env(ament_prefix_path),
                          capture_output=True, text=True, timeout=60, check=True)
    out = proc.stdout + proc.stderr
    result = out.split('RESULT=[', 1)[1].split(']', 1)[0]
    return result, out


def fake_prefix(root: Path, *packages: str) -> Path:
    """A prefix with an ament index registering ``packages`` (as colcon / ROS installs do)."""
    index = root / 'share' / 'ament_index' / 'resource_index' / 'packages'
    index.mkdir(parents=True)
    for p in packages:
        (index / p).write_text('', encoding='utf-8')
    return root


@pytest.fixture
def failing_python(tmp_path: Path) -> str:
    """An 'interpreter' that fails: any use of the Python probe shows in the result."""
    exe = tmp_path / 'no-python'
    exe.write_text('#!/bin/sh\necho "probe was run" >&2\nexit 3\n', encoding='utf-8')
    exe.chmod(0o755)
    return str(exe)


def venv_prefix() -> Path:
    """Where this test's interpreter has the ros-jazzy wheels (independent of the cmake code)."""
    import sysconfig

    # <prefix>/lib/python3.X/site-packages
    purelib = Path(sysconfig.get_paths()['purelib']).resolve()
    assert (purelib / 'rosidl_adapter').is_dir(), 'the venv has no ros-jazzy wheels'
    return purelib.parents[2]


def test_sourced_ros_install_is_left_alone(tmp_path: Path, failing_python: str) -> None:
    ros = fake_prefix(tmp_path / 'opt_ros_jazzy', 'rosidl_typesupport_c', 'rclcpp')
    ws = fake_prefix(tmp_path / 'ws_install', 'my_pkg')
    result, out = detect(tmp_path, python=failing_python,
                         ament_prefix_path=f'{ws}:{ros}')
    assert result == ''
    assert f'ament prefix: {ros} from AMENT_PREFIX_PATH' in out
    assert 'probe was run' not in out and 'no ROS wheels' not in out


def test_venv_wheels_are_found_without_flags(tmp_path: Path) -> None:
    result, out = detect(tmp_path, python=sys.executable)
    assert Path(result).resolve() == venv_prefix(), out
    assert 'ROS wheels, found from rosidl_adapter' in out


def test_workspace_underlay_without_ros_still_finds_the_wheels(tmp_path: Path) -> None:
    """colcon puts the workspace's own install prefixes on AMENT_PREFIX_PATH: not ROS."""
    ws = fake_prefix(tmp_path / 'ws_install', 'rv_te_msgs')
    result, _ = detect(tmp_path, python=sys.executable, ament_prefix_path=str(ws))
    assert Path(result).resolve() == venv_prefix()


def test_explicit_prefix_wins(tmp_path: Path, failing_python: str) -> None:
    result, out = detect(tmp_path, python=failing_python,
                         defines={'ROS_WHEEL_PREFIX': '/some/prefix'})
    assert result == '/some/prefix'
    assert 'probe was run' not in out


def test_pip_build_uses_the_wheels_even_with_ros_sourced(tmp_path: Path) -> None:
    ros = fake_prefix(tmp_path / 'opt_ros_jazzy', 'rosidl_typesupport_c')
    result, _ = detect(tmp_path, python=sys.executable, ament_prefix_path=str(ros),
                       defines={'SKBUILD': '2'})
    assert Path(result).resolve() == venv_prefix()


def test_nothing_found_is_reported_and_empty(tmp_path: Path, failing_python: str) -> None:
    result, out = detect(tmp_path, python=failing_python, ament_prefix_path='')
    assert result == ''
    assert 'has no ROS wheels' in out


def test_fix_drops_only_missing_opt_python_include_dirs(tmp_path: Path) -> None:
    existing = tmp_path / 'inc'
    existing.mkdir()
    missing = '/opt/python/cp311-cp311/include/python3.11'
    (tmp_path / 'CMakeLists.txt').write_text(f'''\
cmake_minimum_required(VERSION 3.21)
project(fixcheck LANGUAGES NONE)
include("{CMAKE_DIR / 'fix_ros_wheel_targets.cmake'}")
add_library(wheel_py INTERFACE IMPORTED)
set_target_properties(wheel_py PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "{missing};{existing}")
add_library(opt_ros INTERFACE IMPORTED)
set_target_properties(opt_ros PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "/opt/ros/jazzy/include")
fix_ros_wheel_imported_targets()
get_target_property(a wheel_py INTERFACE_INCLUDE_DIRECTORIES)
get_target_property(b opt_ros INTERFACE_INCLUDE_DIRECTORIES)
message(STATUS "A=[${{a}}]")
message(STATUS "B=[${{b}}]")
''', encoding='utf-8')
    if Path(missing).exists():
        pytest.skip(f'{missing} exists on this machine')
    proc = subprocess.run([CMAKE, '-S', str(tmp_path), '-B', str(tmp_path / 'b')],
                          env=_env(None), capture_output=True, text=True, timeout=60,
                          check=True)
    assert f'A=[{existing}]' in proc.stdout
    assert 'B=[/opt/ros/jazzy/include]' in proc.stdout


@pytest.mark.slow
def test_configure_with_a_sourced_prefix_takes_the_no_op_path(tmp_path: Path) -> None:
    """The real CMakeLists configured the way a sourced ROS 2 install presents itself:
    AMENT_PREFIX_PATH names an ament prefix (here the venv's, laid out as /opt/ros/jazzy is)
    and its bin/ is on PATH. The detection leaves it alone and rosidl finds everything."""
    import sysconfig

    prefix = venv_prefix()
    env = _env(str(prefix))
    env['PATH'] = f'{Path(sysconfig.get_paths()["scripts"])}:{env.get("PATH", "")}'
    proc = subprocess.run(
        [CMAKE, '-S', str(CMAKE_DIR.parent), '-B', str(tmp_path / 'build'),
         f'-DPython3_EXECUTABLE={sys.executable}'],
        env=env, capture_output=True, text=True, timeout=300, check=False)
    out = proc.stdout + proc.stderr
    assert proc.returncode == 0, out[-3000:]
    assert f'ament prefix: {prefix} from AMENT_PREFIX_PATH' in out
    assert 'ROS wheels, found from rosidl_adapter' not in out
