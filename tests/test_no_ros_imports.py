"""The pure packages import and work with rclpy absent (offline analysis on a laptop)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

HIDE_ROS = r'''
import importlib.abc, sys
class HideRos(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name.split('.')[0] in {'rclpy', 'rv_te_msgs', 'rosidl_runtime_py', 'rosgraph_msgs',
                                  'diagnostic_msgs'}:
            raise ModuleNotFoundError(f'hidden for this test: {name}', name=name)
        return None
sys.meta_path.insert(0, HideRos())
import pkgutil, importlib
mods = []
for pkg_name in ('sim', 'rv_te_bench.core', 'rv_te_bench.io', 'rv_te_bench.report'):
    try:
        pkg = importlib.import_module(pkg_name)
    except ModuleNotFoundError as exc:
        if exc.name == pkg_name:
            continue
        raise
    mods.append(pkg_name)
    for info in pkgutil.iter_modules(pkg.__path__, pkg_name + '.'):
        importlib.import_module(info.name)
        mods.append(info.name)
assert 'rclpy' not in sys.modules
print(' '.join(mods))
'''


def test_pure_packages_import_without_rclpy() -> None:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    out = subprocess.run([sys.executable, '-c', HIDE_ROS], cwd=ROOT, env=env,
                         capture_output=True, text=True, timeout=120, check=False)
    assert out.returncode == 0, out.stderr
    imported = out.stdout.split()
    assert 'sim' in imported
    assert 'rv_te_bench.core' in imported
    assert 'rv_te_bench.core.advice' in imported
