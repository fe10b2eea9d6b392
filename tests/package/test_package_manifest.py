"""The ament_python package rv_te_bench (rv_te_bench_ros/): manifest, versions, executables.

Fast checks that need no build: package.xml is a valid format-3 manifest (catkin_pkg, the
parser colcon and rosdep use), names every ROS package the code imports, and agrees in version
with the pip distribution; every executable's entry point exists.
"""

from __future__ import annotations

import ast
import importlib
import sysconfig
import tomllib
from pathlib import Path

import pytest

from tests.package.conftest import PKG_DIR, REPO, setup_py_value


def manifest():
    from catkin_pkg.package import parse_package

    return parse_package(str(PKG_DIR / 'package.xml'))


def test_manifest_is_valid_ament_python() -> None:
    pkg = manifest()
    pkg.validate()
    assert pkg.name == 'rv_te_bench'
    assert pkg.package_format == 3
    assert pkg.get_build_type() == 'ament_python'
    assert 'rv_te_msgs' in {d.name for d in pkg.build_depends}   # colcon builds it first


def test_versions_agree() -> None:
    pyproject = tomllib.loads((REPO / 'pyproject.toml').read_text(encoding='utf-8'))
    version = pyproject['project']['version']
    assert manifest().version == version
    assert setup_py_value('VERSION') == version


def _ros_packages_installed() -> set[str]:
    """Package names registered in the venv's ament index (the ros-jazzy wheels)."""
    prefix = Path(sysconfig.get_paths()['purelib']).parents[2]
    index = prefix / 'share' / 'ament_index' / 'resource_index' / 'packages'
    return {p.name for p in index.iterdir()} | {'rv_te_msgs'}


def _imported_top_level(root: Path) -> set[str]:
    names: set[str] = set()
    for path in root.rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text(encoding='utf-8'))):
            if isinstance(node, ast.Import):
                names |= {a.name.split('.')[0] for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                names.add(node.module.split('.')[0])
    return names


def test_manifest_names_every_ros_package_the_code_imports() -> None:
    ros = _ros_packages_installed()
    imported = (_imported_top_level(REPO / 'rv_te_bench') | _imported_top_level(REPO / 'sim'))
    needed = {n for n in imported if n in ros}
    assert {'rclpy', 'rv_te_msgs'} <= needed   # the scan sees the imports at all
    pkg = manifest()
    declared = {d.name for d in [*pkg.exec_depends, *pkg.build_depends]}
    assert needed <= declared, f'missing from package.xml: {sorted(needed - declared)}'


@pytest.mark.parametrize('exe', sorted(setup_py_value('EXECUTABLES')))  # type: ignore[arg-type]
def test_every_executable_has_its_entry_point(exe: str) -> None:
    target = setup_py_value('EXECUTABLES')[exe]  # type: ignore[index]
    module, func = target.split(':')
    assert callable(getattr(importlib.import_module(module), func))


def test_setup_cfg_installs_executables_where_ros2_run_looks() -> None:
    import configparser

    cfg = configparser.ConfigParser()
    cfg.read(PKG_DIR / 'setup.cfg')
    assert cfg['install']['install_scripts'] == '$base/lib/rv_te_bench'
    assert cfg['develop']['script_dir'] == '$base/lib/rv_te_bench'
    assert (PKG_DIR / 'resource' / 'rv_te_bench').is_file()
    for link in ('rv_te_bench', 'sim'):
        assert (PKG_DIR / link).resolve() == (REPO / link).resolve()
