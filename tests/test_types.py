"""The type check of the offline packages, mypy --strict (``[tool.mypy]`` in pyproject.toml).

``make lint`` runs it (and so CI, before the tests); it runs here too, as
tests/test_layers.py runs import-linter, so that a change that breaks the types fails the
quick loop (``make test-fast``) before it reaches CI. The second test shows, on a copy of
the packages with a type error written into the TE core, that the check catches one.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MYPY = Path(sys.executable).parent / 'mypy'

pytestmark = pytest.mark.skipif(not MYPY.exists(),
                                reason='mypy is not installed (pip install .[test])')


def _mypy(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    return subprocess.run([str(MYPY), *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=900, check=False)


def test_the_offline_packages_type_check() -> None:
    out = _mypy(ROOT)
    assert out.returncode == 0, out.stdout[-4000:] + out.stderr
    assert 'Success: no issues found' in out.stdout


@pytest.mark.slow
def test_a_type_error_is_caught(tmp_path: Path) -> None:
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc', '*.so')
    for pkg in ('rv_te_bench', 'sim'):
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=ignore)
    shutil.copy(ROOT / 'pyproject.toml', tmp_path / 'pyproject.toml')
    # mypy's own cache of the repository (the first test, or make lint, wrote it) seeds the
    # copy's, as a developer's incremental run: mypy checks every cached module against its
    # source hash and re-checks te.py and what depends on it; the numpy / scipy stubs are
    # not analysed again (they were most of this test's two minutes)
    if (ROOT / '.mypy_cache').is_dir():
        shutil.copytree(ROOT / '.mypy_cache', tmp_path / '.mypy_cache')
    te = tmp_path / 'rv_te_bench' / 'core' / 'te.py'
    # the record's crank order read as text: what a misspelt or mistyped field looks like
    te.write_text(te.read_text(encoding='utf-8')
                  + '\n\ndef _planted(info: BenchInfoData) -> str:\n'
                    '    return info.crank_per_input\n'
                    '\n\nfrom sim.bench_info import BenchInfoData  # noqa: E402\n',
                  encoding='utf-8')
    out = _mypy(tmp_path, '--cache-dir', str(tmp_path / '.mypy_cache'))
    assert out.returncode == 1, out.stdout[-4000:] + out.stderr
    assert 'rv_te_bench/core/te.py' in out.stdout
    assert '[return-value]' in out.stdout
    assert 'Found 1 error' in out.stdout
