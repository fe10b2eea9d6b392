"""Issue 33 s.6: colcon took the repository's root (its setup.py, for the pip distribution's C
extension) for a package and printed a 33 KB ERROR traceback on every ``colcon list`` /
``colcon build``. The extension is declared in pyproject.toml now (setuptools >= 74.1
ext-modules) and the root has no setup.py: colcon finds exactly the two ROS packages and says
nothing on stderr. (The full ``colcon build`` is tests/package/test_colcon_workspace.py, slow.)
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
COLCON = Path(sys.executable).parent / 'colcon'
IGNORE = shutil.ignore_patterns('.git', '.venv', '.hypothesis', '.pytest_cache', '__pycache__',
                                '*.egg-info', '*.so', 'build', 'install', 'log', 'bags', 'tests',
                                'benchmarks', 'out', 'mutants')


@pytest.mark.skipif(not COLCON.exists(), reason='colcon is not installed (make venv does)')
@pytest.mark.timeout(120)
def test_colcon_list_is_clean(tmp_path: Path) -> None:
    shutil.copytree(REPO, tmp_path / 'src' / 'rv-te-bench', symlinks=True, ignore=IGNORE)
    env = {k: v for k, v in os.environ.items()
           if k not in {'AMENT_PREFIX_PATH', 'CMAKE_PREFIX_PATH', 'COLCON_PREFIX_PATH'}}
    env['PATH'] = f'{COLCON.parent}:{env.get("PATH", "/usr/bin:/bin")}'
    done = subprocess.run([str(COLCON), 'list'], cwd=tmp_path, env=env, capture_output=True,
                          text=True, timeout=100, check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    assert done.stderr == '', done.stderr[-2000:]
    rows = sorted(line.split('\t')[0] for line in done.stdout.splitlines())
    assert rows == ['rv_te_bench', 'rv_te_msgs'], done.stdout
    assert not (REPO / 'setup.py').exists()
