"""The launcher's grace for a stopping node covers the work a busy node may finish.

A busy node (the compensation node's phase search) may take FINISH_MAX_S = 8 s after its
SIGTERM to finish and publish its result, then drains and exits. The launcher waited 10 s
before it escalated and said "node 'compensation' did not stop on SIGTERM" (exit 1): on a
machine at load 13 the drain and exit took more than the 2 s left, and a session that had
stopped as designed failed. Real processes: a stand-in node process that takes as long as
such a node, stopped by the launcher's own stop().
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from rv_te_bench.cli.test import simulated_session_spec
from rv_te_bench.launch.session import NodeProcess, Session
from rv_te_bench.nodes.common import FINISH_MAX_S

#: A node that, once told to stop, finishes its work for FINISH_MAX_S and then takes 2.5 s
#: more to drain and exit (what a loaded machine gave it), and exits 0.
SLOW_STOP = f'''
import signal, sys, time
stop = []
signal.signal(signal.SIGTERM, lambda *_: stop.append(time.monotonic()))
print('ready', flush=True)
while not stop:
    time.sleep(0.01)
while time.monotonic() < stop[0] + {FINISH_MAX_S} + 2.5:
    time.sleep(0.01)
sys.exit(0)
'''


@pytest.mark.timeout(60)
def test_a_node_finishing_its_work_then_slow_to_exit_is_waited_for(tmp_path: Path) -> None:
    spec = simulated_session_spec(tmp_path, preset='li2023-rv', te_mode='dte')
    session = Session(spec, log=lambda _s: None)
    proc = subprocess.Popen([sys.executable, '-c', SLOW_STOP], stdout=subprocess.PIPE)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b'ready'
        session.procs['compensation'] = NodeProcess('compensation', proc)
        t0 = time.monotonic()
        codes = session.stop(settle_s=0.0)
        took = time.monotonic() - t0
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert session.failures == [], session.failures
    assert codes == {'compensation': 0}
    assert FINISH_MAX_S + 2.0 < took < FINISH_MAX_S + 10.0, took


#: A node that notes a step of its stop (as run_node does) and then never ends on SIGTERM.
STUCK_STOP = '''
import os, signal, sys, time
signal.signal(signal.SIGTERM, lambda *_: None)
from rv_te_bench.nodes.common import dump_stacks_on_request, note_stop_phase
assert dump_stacks_on_request()
note_stop_phase("waiting for its readers' acknowledgements")
print('ready', flush=True)
while True:
    time.sleep(0.01)
'''


@pytest.mark.timeout(60)
def test_a_node_that_does_not_stop_is_named_with_where_it_was(tmp_path: Path) -> None:
    """The stop says which node did not stop, how long it was waited for, the step of its
    stop it was at, and how it ended, and the node prints its threads' stacks before it is
    killed: a benchmark once saw a session end with "a node's non-zero exit" and could not
    tell which node, or why."""
    from rv_te_bench.nodes.params import STOP_PHASE_FILE_ENV

    spec = simulated_session_spec(tmp_path, preset='li2023-rv', te_mode='dte')
    session = Session(spec, log=lambda _s: None)
    env = dict(os.environ, **{STOP_PHASE_FILE_ENV: str(session._phase_path('te_node'))})
    err = tmp_path / 'te_node.err'
    with err.open('wb') as f:
        proc = subprocess.Popen([sys.executable, '-c', STUCK_STOP], stdout=subprocess.PIPE,
                                stderr=f, env=env)
    try:
        assert proc.stdout is not None and proc.stdout.readline().strip() == b'ready'
        session.procs['te_node'] = NodeProcess('te_node', proc)
        codes = session.stop(grace_s=1.0, settle_s=0.0)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert codes == {'te_node': -signal.SIGKILL}
    assert len(session.failures) == 1, session.failures
    msg = session.failures[0]
    assert msg.startswith("node 'te_node' did not stop on SIGTERM within 1."), msg
    assert "(at: waiting for its readers' acknowledgements (0.0 s into its stop))" in msg, msg
    assert msg.endswith('; killed (SIGKILL)'), msg
    assert session.stop_s['te_node'] is not None and session.stop_s['te_node'] >= 4.0
    stacks = err.read_text(encoding='utf-8')
    assert '(most recent call first)' in stacks and 'File "<string>", line 9' in stacks, stacks
