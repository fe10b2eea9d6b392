"""The ament_python side of rv_te_bench: the same sources as the pip distribution.

colcon builds this folder (package.xml here); ``rv_te_bench`` and ``sim`` are links to the
repository's packages, so there is one copy of the code. The pip install
(``pip install -e .`` at the repository root, pyproject.toml) stays as it is.
"""

from __future__ import annotations

import sys
from pathlib import Path

from setuptools import Extension, find_packages, setup

PACKAGE = 'rv_te_bench'
HERE = Path(__file__).resolve().parent
# = package.xml = pyproject.toml (checked by tests/package/test_package_manifest.py,
# test_versions_agree)
VERSION = '0.1.0'

# executable in lib/rv_te_bench/ -> entry point
EXECUTABLES = {
    'bench_node': 'rv_te_bench.nodes.bench_node:main',
    'test_sequencer': 'rv_te_bench.nodes.test_sequencer:main',
    'te_node': 'rv_te_bench.nodes.te_node:main',
    'joint_state_adapter': 'rv_te_bench.nodes.joint_state_adapter:main',
    'compensation_node': 'rv_te_bench.nodes.compensation_node:main',
    'recorder': 'rv_te_bench.nodes.recorder:main',
    'replay': 'rv_te_bench.nodes.replay:main',
    'rv-te': 'rv_te_bench.cli.main:main',
}


def _files(pattern: str) -> list[str]:
    return sorted(str(p.relative_to(HERE)) for p in HERE.glob(pattern))


setup(
    name=PACKAGE,
    version=VERSION,
    packages=find_packages(include=['rv_te_bench', 'rv_te_bench.*', 'sim', 'sim.*']),
    package_data={'rv_te_bench': ['launch/*.yaml', 'py.typed', 'io/legacy_msgs/*.msg',
                                  'acceptance/plans/*.yaml',
                                  'acceptance/tolerances/*.yaml'],
                  'sim': ['preset_data/*.toml']},
    data_files=[
        ('share/ament_index/resource_index/packages', [f'resource/{PACKAGE}']),
        (f'share/{PACKAGE}', ['package.xml']),
        # launch and parameter files: the ones rv-te launch uses (rv_te_bench/launch/)
        (f'share/{PACKAGE}/launch', _files('rv_te_bench/launch/*.yaml')),
    ],
    # the optional compiled resampler, as in pyproject.toml's ext-modules (numpy path without it)
    ext_modules=[Extension('rv_te_bench.core._lagrange', ['rv_te_bench/core/_lagrange.c'],
                           extra_compile_args=[] if sys.platform == 'win32'
                           else ['-O3', '-ffp-contract=off'], optional=True)],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='rv-te-bench developers',
    maintainer_email='dev@rv-te-bench.invalid',
    description='Transmission-error testing of precision robot reducers with ROS 2 Jazzy',
    license='Apache-2.0',
    entry_points={'console_scripts': [f'{k} = {v}' for k, v in EXECUTABLES.items()]},
)
