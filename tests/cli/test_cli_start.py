"""What every ``rv-te`` command pays before it does anything: building the parser imports
no subcommand's machinery (the suite starts the command hundreds of times, users too)."""

from __future__ import annotations

import os
import subprocess
import sys


def test_the_parser_does_not_import_the_live_page_server() -> None:
    """launch, test, replay and dashboard show the page's default ports in --help; those
    came from the page's server module, so every command imported it (asyncio, http,
    email, ssl: ~0.085 CPU s each time). Fails before: True."""
    code = ('import sys; from rv_te_bench.cli.main import build_parser; build_parser(); '
            "print(sorted(m for m in ('rv_te_bench.dashboard.run', "
            "'rv_te_bench.dashboard.server') if m in sys.modules))")
    env = {k: v for k, v in os.environ.items() if k != '_ROS_WHEELS_BOOTSTRAP_COMPLETE'}
    p = subprocess.run([sys.executable, '-c', code], capture_output=True, text=True,
                       timeout=120, env=env, check=False)
    assert p.returncode == 0, p.stderr
    assert p.stdout.strip() == '[]'
