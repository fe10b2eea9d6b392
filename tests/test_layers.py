"""The layering of docs/ARCHITECTURE.md, checked by import-linter (``[tool.importlinter]``).

The first test runs the contracts on this repository; the second shows that they catch a
lower layer importing a higher one, and ROS imported into the pure core, on a copy of the
packages with both violations written in; the third, that a circle between two modules of
a folder held by a function-local import (the kind io/ had) is caught; the fourth, that the
circles acceptance/, cli/, core/ and report/ once had (a step kind and the runner, the
``rv-te test`` routes and the command, a result type and its budgets, held by function-local
and type-checking imports) are caught in every package.
(tests/test_no_ros_imports.py checks the other side: the pure packages really import and
run with rclpy absent.)
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
LINT_IMPORTS = Path(sys.executable).parent / 'lint-imports'

pytestmark = pytest.mark.skipif(not LINT_IMPORTS.exists(),
                                reason='import-linter is not installed (pip install .[test])')


def _lint(cwd: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env.pop('_ROS_WHEELS_BOOTSTRAP_COMPLETE', None)
    # the copy's packages, not the editable install's, are the ones analysed
    env['PYTHONPATH'] = str(cwd)
    return subprocess.run([str(LINT_IMPORTS), '--no-cache'], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120, check=False)


def test_the_repository_keeps_its_layers() -> None:
    out = _lint(ROOT)
    assert out.returncode == 0, out.stdout + out.stderr
    assert '0 broken' in out.stdout


def _copy(tmp_path: Path) -> None:
    ignore = shutil.ignore_patterns('__pycache__', '*.pyc')
    for pkg in ('rv_te_bench', 'sim'):
        shutil.copytree(ROOT / pkg, tmp_path / pkg, ignore=ignore)
    shutil.copy(ROOT / 'pyproject.toml', tmp_path / 'pyproject.toml')


def test_an_upward_import_and_rclpy_in_core_are_caught(tmp_path: Path) -> None:
    _copy(tmp_path)
    assert _lint(tmp_path).returncode == 0     # the copy alone is clean

    te = tmp_path / 'rv_te_bench' / 'core' / 'te.py'
    te.write_text(te.read_text(encoding='utf-8')
                  + '\n\ndef _violation() -> None:\n'
                    '    import rclpy  # noqa: F401, PLC0415\n'
                    '    from rv_te_bench.report import analysis  # noqa: F401, PLC0415\n',
                  encoding='utf-8')
    out = _lint(tmp_path)
    text = out.stdout + out.stderr
    assert out.returncode != 0, text
    assert 'BROKEN' in text
    assert 'rv_te_bench.core.te -> rclpy' in text
    assert 'rv_te_bench.core.te -> rv_te_bench.report.analysis' in text


@pytest.mark.parametrize(('lower', 'upper'), [
    ('rv_te_bench/io/_bag_types.py', 'rv_te_bench.io.bag_reader'),
    ('rv_te_bench/launch/checks.py', 'rv_te_bench.launch.session'),   # the old circle
])
def test_a_circle_inside_a_folder_is_caught(tmp_path: Path, lower: str, upper: str) -> None:
    """The record types (lowest floor) reaching up to a reader inside a function."""
    _copy(tmp_path)
    module = tmp_path / lower
    module.write_text(module.read_text(encoding='utf-8')
                      + f'\n\ndef _violation() -> None:\n'
                        f'    import {upper}  # noqa: F401, PLC0415\n',
                      encoding='utf-8')
    out = _lint(tmp_path)
    text = out.stdout + out.stderr
    assert out.returncode != 0, text
    package = upper.rsplit('.', 1)[0]
    assert f'No cycles are allowed in {package}' in text


#: The four circles once inside a package, each planted back (module, the module it takes from,
#: how): a type-checking import (the kind that tied the step kinds to the runner, the
#: identification to its budgets, the TE trace to the budgets) and a function-local one (the
#: kind that tied the ``rv-te test`` routes to the command).
_OLD_CIRCLES = (
    ('rv_te_bench/acceptance/loss_steps.py', 'rv_te_bench.acceptance.runner', 'typing'),
    ('rv_te_bench/cli/_test_report.py', 'rv_te_bench.cli.test', 'local'),
    ('rv_te_bench/core/identification.py', 'rv_te_bench.core.identify', 'typing'),
    ('rv_te_bench/report/trace.py', 'rv_te_bench.report.results', 'typing'),
)


def test_the_old_circles_are_caught_in_every_package(tmp_path: Path) -> None:
    """One copy with the four circles written back (one lint run): each package is named."""
    _copy(tmp_path)
    for lower, upper, how in _OLD_CIRCLES:
        module = tmp_path / lower
        planted = ('\n\nimport typing  # noqa: E402\n\nif typing.TYPE_CHECKING:\n'
                   f'    import {upper}  # noqa: F401\n' if how == 'typing' else
                   '\n\ndef _violation() -> None:\n'
                   f'    import {upper}  # noqa: F401, PLC0415\n')
        module.write_text(module.read_text(encoding='utf-8') + planted, encoding='utf-8')
    out = _lint(tmp_path)
    text = out.stdout + out.stderr
    assert out.returncode != 0, text
    for _, upper, _ in _OLD_CIRCLES:
        assert f'No cycles are allowed in {upper.rsplit(".", 1)[0]}.' in text, text
