"""A plan run through setpoints against :class:`sim.commanded.CommandedBench`, without ROS.

The loop the ``test_sequencer`` runs over the middleware (setpoints out to the forward
command controllers, samples back through ``joint_states`` and the JointState adapter),
closed here in process: the same :class:`~rv_te_bench.acceptance.driver.ProgramDriver`,
the same step runners and report. Tests use it to check the driver against the simulated
bench quickly; the node tests check the middleware path against this one.
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING, Any

import numpy as np

from rv_te_bench.acceptance.driver import ZERO, DriverSettings, ProgramDriver, Setpoint
from rv_te_bench.acceptance.runner import StepRunner, build_report
from sim.commanded import BenchCommand

if TYPE_CHECKING:
    from collections.abc import Callable

    from rv_te_bench.acceptance.driver import SafetyLimits
    from rv_te_bench.acceptance.plan import OperatorStep, TestPlan
    from rv_te_bench.acceptance.tolerance import Measured, ToleranceProfile
    from sim.bench import BenchBlock
    from sim.commanded import CommandedBench

__all__ = ['feed_parts', 'run_plan_commanded', 'to_command']


def to_command(sp: Setpoint) -> BenchCommand:
    """A driver setpoint as the simulated bench's command."""
    return BenchCommand(drive_velocity_rad_s=sp.drive_velocity_rad_s, load_mode=sp.load_mode,
                        load_value=sp.load_value)


def feed_parts(runner: StepRunner, parts: list[tuple[int, int, int]], theta_in: np.ndarray,
               theta_out: np.ndarray, torque_out: np.ndarray, last: list[int],
               torque_in: np.ndarray | None = None,
               temp_case: np.ndarray | None = None) -> float:
    """Hand the segments' slices of a block to the runner; returns the live value.

    ``last`` holds the segment fed last (a one-element list, updated), so that the live
    value restarts with each new segment. ``torque_in`` / ``temp_case``: the block's input
    torque and case temperature (None or empty: the bench has no such channel).
    """
    live = float('nan')
    for seg, a, b in parts:
        if seg != last[0]:
            runner.next_segment()
            last[0] = seg
        tq = torque_out[a:b] if torque_out.size else torque_out
        t_in = torque_in[a:b] if torque_in is not None and torque_in.size else None
        temp = temp_case[a:b] if temp_case is not None and temp_case.size else None
        live = runner.feed(seg, theta_in[a:b], theta_out[a:b], tq, t_in, temp)
    return live


def run_plan_commanded(plan: TestPlan, profile: ToleranceProfile, *, bench: CommandedBench,
                       serial: str, operator: str, limits: SafetyLimits,
                       settings: DriverSettings | None = None,
                       conditions: dict[str, Any] | None = None,
                       on_block: Callable[[BenchBlock], None] | None = None,
                       acknowledge: Callable[[OperatorStep], str] | None = None,
                       ) -> dict[str, Any]:
    """Run every step through setpoints and report (see the module docstring).

    Args:
        plan, profile: The validated plan and tolerance profile.
        bench: The simulated bench taking setpoints.
        serial, operator: Unit identity.
        limits: Safety limits checked on every sample read back.
        settings: Reach criteria (default :class:`DriverSettings`).
        conditions: Test conditions for the record.
        on_block: Called with every block read back (a recording).
        acknowledge: Called for an operator step: '' acknowledged, else the reason it was
            not (the test is aborted with it). None: acknowledged at once.

    Returns:
        The report; an aborted test has verdict 'aborted' and the reason.
    """
    settings = settings or DriverSettings()
    info = bench.sim.info
    started = dt.datetime.now(dt.UTC).isoformat(timespec='seconds')
    results: list[tuple[list[Measured], dict[str, Any]]] = []
    block_s = info.block_size / info.sample_rate_hz
    for step in plan.steps:
        runner = StepRunner(step, info)
        program = runner.program()
        if not program:                       # an operator step
            why = acknowledge(step) if acknowledge is not None else ''  # type: ignore[arg-type]
            if why:
                bench.set(to_command(ZERO))
                return build_report(plan=plan, profile=profile, info=info, serial=serial,
                                    operator=operator, results=results, conditions=conditions,
                                    started_utc=started, status='aborted', why=why)
            results.append(runner.result())
            continue
        driver = ProgramDriver(program, limits=limits, settings=settings,
                               sample_rate_hz=info.sample_rate_hz)
        bench.set(to_command(driver.start()))
        budget = sum(float(s.get('duration_s', 0.0)) for s in program) / block_s \
            + len(program) * settings.reach_timeout_s / block_s + 1000
        last = [-1]
        for _ in range(int(budget)):
            block = bench.next_block()
            if on_block is not None:
                on_block(block)
            t = block.t0_s + np.asarray(block.time_offset_s)
            tq = np.asarray(block.torque_out_nm)
            upd = driver.push(t, block.theta_in_rad, block.theta_out_rad,
                              -tq if tq.size else None)
            feed_parts(runner, upd.parts, np.asarray(block.theta_in_rad),
                       np.asarray(block.theta_out_rad), tq, last,
                       None if block.torque_in_nm is None else np.asarray(block.torque_in_nm),
                       None if block.temp_case_degc is None
                       else np.asarray(block.temp_case_degc))
            if upd.setpoint is not None:
                bench.set(to_command(upd.setpoint))
            if upd.abort:
                results.append(runner.result())
                return build_report(plan=plan, profile=profile, info=info, serial=serial,
                                    operator=operator, results=results[:-1],
                                    conditions=conditions, started_utc=started,
                                    status='aborted', why=f'step {step.name!r}: {upd.abort}')
            if upd.finished:
                break
        else:
            bench.set(to_command(ZERO))
            return build_report(plan=plan, profile=profile, info=info, serial=serial,
                                operator=operator, results=results, conditions=conditions,
                                started_utc=started, status='aborted',
                                why=f'step {step.name!r}: the program did not end')
        measured, details = runner.result()
        details['segments_s'] = [list(b) for b in driver.boundaries]
        results.append((measured, details))
    return build_report(plan=plan, profile=profile, info=info, serial=serial, operator=operator,
                        results=results, conditions=conditions, started_utc=started)
