"""A Ctrl-C while ``rv-te`` starts (issue #16, seen again under load in the orphan test at
0.7 s): wherever it lands among the command's own imports, the command ends with one line
and exit code 130, never a traceback. The interrupt is raised by an import hook at a named
module, so the test does not race the machine's load."""

from __future__ import annotations

import subprocess
import sys

import pytest

SCRIPT = '''
import sys

class Interrupt:
    def find_spec(self, name, path=None, target=None):
        if name == {module!r}:
            raise KeyboardInterrupt
        return None

sys.modules.pop({module!r}, None)
sys.meta_path.insert(0, Interrupt())
from rv_te_bench.cli.main import main
sys.exit(main(['presets']))
'''


@pytest.mark.parametrize('module', [
    'argparse',                # the command module's own first imports
    'rv_te_bench.errors',      # the error types main() catches
    'sim.errors',
    'rv_te_bench.cli.launch',  # the subcommands
])
def test_ctrl_c_during_the_start_up_imports(module: str) -> None:
    proc = subprocess.run([sys.executable, '-c', SCRIPT.format(module=module)],
                          capture_output=True, text=True, timeout=120, check=False)
    assert 'Traceback' not in proc.stderr, proc.stderr
    assert (proc.returncode, proc.stderr.strip()) == (130, 'interrupted')


def test_the_command_runs_without_the_hook() -> None:
    """The script itself works (the hook is what interrupts)."""
    proc = subprocess.run([sys.executable, '-c', SCRIPT.format(module='no.such.module')],
                          capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 0, proc.stderr
    assert 'wang2020-2kv' in proc.stdout
