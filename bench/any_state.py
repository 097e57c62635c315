"""Motion from any state over the real nodes: goal-to-handover latency, operator latency, tick lateness.

Starts the planner, streamer and sim executables in a private ROS graph and measures:

- **goal-to-handover latency**: a 0.3 m move in 3 s, and at 40 % of it a new goal 0.2 m further
  (as soon as possible, from where the motion is): the time from sending the goal (handing it to
  rclpy's ``send_goal_async``) to the handover tick (the tick the streamer takes it over at: a change
  arriving after its stamp is delayed to the tick after the one the streamer had sampled when it
  arrived), ``--repeats`` times per method (nvf, rvf, zv). Targets: median <= 50 ms for NVF/RVF, <= 5 ms for a shaper.
  A shaper's handovers alternate with the planner's ``handover_warmup`` on (its default) and off,
  so what the warm-up gains and costs (the CPU share of the planner and its solver processes over each
  move, retarget and return) is a ratio measured in the same run.
- **handover warm-up**: over a 3 s ZV move, the rehearsals the planner's goals' thread made per
  ``handover_warmup`` period (1 = every period; a busy host lets fewer happen) and how long each took
  (the goal's execute status on /diagnostics), ``--settles`` moves.
- **settle**: the crane pushed aside (the sim's ``~/push``), then ``~/settle``: the time from the call
  to the settle motion's stamp, ``--settles`` times.
- **operator command latency**: in operator mode (operator_shaper zv, whose first impulse is at 0),
  a cmd_vel published here, then the first 1 kHz reference sample that differs from the one before:
  its stamp (the tick it is due) less the publish time. Target: <= 2 ms plus the shaper's delay (0).
- **tick lateness while shaping online**: the streamer's own p99 tick lateness (its /diagnostics,
  once a second) holding in trajectory mode, and in operator mode with a stick moving the crane back
  and forth: the ratio. Target: unchanged (the machine is shared: compare the ratio, not the figures).

Prints one JSON object.

    .venv/bin/python bench/any_state.py [--repeats 8]
"""
import argparse
import json
import sys
import time

import numpy as np


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--repeats', type=int, default=8, help='handovers per method (default 8)')
    ap.add_argument('--commands', type=int, default=20, help='operator commands timed (default 20)')
    ap.add_argument('--window', type=float, default=5.0, help='seconds of tick lateness per window (default 5)')
    ap.add_argument('--rounds', type=int, default=3, help='windows per mode, alternating (default 3)')
    ap.add_argument('--methods', default='nvf,rvf,zv', help='methods retargeted (default nvf,rvf,zv)')
    ap.add_argument('--settles', type=int, default=5, help='settles after a push, and warm-up moves (default 5)')
    args = ap.parse_args()
    args.methods = [m for m in args.methods.split(',') if m]
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        return measure(args, env)


def _at_rest(driver) -> bool:
    """Whether the streamer reports holding (its newest stream status)."""
    from crane_msgs_py.runtime.diagnostics import status_values
    statuses = driver.planner.diagnostics.statuses('crane_streamer: stream')
    return bool(statuses) and 'holding' in status_values(statuses[-1]).get('state', '')


def measure(args, env) -> int:
    import tempfile
    from pathlib import Path

    import rclpy
    from geometry_msgs.msg import Twist

    from crane_msgs_py.messages.names import CMD_VEL_TOPIC
    from crane_msgs_py.runtime.diagnostics import status_values
    from crane_planner.tools.harness import CraneHarness, start_crane_nodes
    from crane_planner.tools.processes import NodeGroup

    ns = '/bench_any_state'
    result = {}
    with NodeGroup(env, Path(tempfile.mkdtemp(prefix='any-state-bench-'))) as nodes:
        start_crane_nodes(nodes, ns)
        driver = CraneHarness(ns, nodes, node_name='any_state_bench')
        try:
            driver.wait_until_up(120.0)
            # -- goal-to-handover latency
            from service_load import cpu_s  # (bench/: the planner and its solver processes)

            from crane_planner.planning.methods import Family, family_of
            from crane_planner.serving.config import PARAMETERS
            warmup = PARAMETERS['handover_warmup'][0]  # the default, restored after each handover timed without
            planner_pid = next(p.popen.pid for p in nodes.processes if p.name == 'planner')

            def handover(method):
                """One move, retargeted at 40 %, and back: (goal to handover ms, the planner's CPU share)."""
                wall, cpu = time.monotonic(), cpu_s(planner_pid)
                start, _, _ = driver.move(method, None, 0.3, 3.0, settle=0.3)
                driver.sleep(max(0.0, (start + 1_200_000_000 - driver.now_ns()) * 1e-9))
                taken = driver.retarget(method, 0.5, 3.0, settle=0.3)
                sent = driver.planner.last_sent_ns
                driver.outcome(start)
                driver.move_result(taken)
                back, _, _ = driver.move('zv', None, 0.0, 3.0, settle=0.3)
                driver.move_result(back)
                driver.reset_sim()
                return (taken - sent) * 1e-6, (cpu_s(planner_pid) - cpu) / (time.monotonic() - wall)

            def summary(samples):
                ms, share = np.array(samples).T
                return {'median_ms': round(float(np.median(ms)), 2), 'p90_ms': round(float(np.percentile(ms, 90)), 2),
                        'max_ms': round(float(np.max(ms)), 2), 'n': len(ms),
                        'planner_cpu_share': round(float(np.mean(share)), 3)}

            latency, cold = {}, {}
            for method in args.methods:
                samples, without = [], []
                for _ in range(args.repeats):
                    samples.append(handover(method))
                    if family_of(method) is not Family.VARIATIONAL:  # the same with the warm-up off, in turn
                        driver.set_parameters('planner', {'handover_warmup': 0.0})
                        try:
                            without.append(handover(method))
                        finally:
                            driver.set_parameters('planner', {'handover_warmup': warmup})
                latency[method] = summary(samples)
                if without:
                    cold[method] = summary(without)
            result['goal_to_handover'] = latency
            result['goal_to_handover_targets_met'] = all(
                v['median_ms'] <= (50.0 if family_of(m) is Family.VARIATIONAL else 5.0) for m, v in latency.items())
            if cold:
                result['goal_to_handover_without_warmup'] = cold
                result['warmup_latency_ratio'] = {m: round(latency[m]['median_ms'] / v['median_ms'], 2)
                                                  for m, v in cold.items()}

            # -- the handover warm-up: how often the goals' thread rehearsed during a motion, how long each took
            from crane_msgs_py.runtime.diagnostics import status_float
            rehearsals = []
            for _ in range(args.settles):
                mark = driver.planner.diagnostics.mark()
                start, _, _ = driver.move('zv', None, 0.3, 3.0, settle=0.2)
                driver.move_result(start)
                status = driver.planner.diagnostics.wait_for(after=mark, name='crane_planner: execute', timeout=5.0)
                if status is not None:  # from its trajectory sent (publish_lead before its start) to its end
                    periods = (3.0 + 0.3) / warmup
                    rehearsals.append((status_float(status, 'handover_warmups') / periods,
                                       status_float(status, 'handover_warmup_ms')))
                back, _, _ = driver.move('zv', None, 0.0, 3.0, settle=0.2)
                driver.move_result(back)
            if rehearsals:
                share, each = np.array(rehearsals).T
                result['handover_warmup'] = {'period_s': warmup, 'rehearsed_share_of_periods_median':
                                             round(float(np.median(share)), 3),
                                             'rehearsal_ms_median': round(float(np.median(each)), 3),
                                             'rehearsal_ms_max': round(float(np.max(each)), 3), 'n': len(share)}

            # -- settle: from the ~/settle call to the settle motion's stamp, a push's swing damped
            after_call = []
            for _ in range(args.settles):
                driver.reset_sim()
                driver.push_sim()
                driver.sleep(1.0)
                called = driver.now_ns()
                stamp, _ = driver.settle()
                after_call.append((stamp - called) * 1e-6)
                driver.sleep(max(0.0, (stamp - driver.now_ns()) * 1e-9 + 4.0))  # the settle over
            driver.reset_sim()
            result['settle_call_to_stamp_ms'] = {'median': round(float(np.median(after_call)), 2),
                                                 'p90': round(float(np.percentile(after_call, 90)), 2),
                                                 'max': round(float(np.max(after_call)), 2), 'n': len(after_call)}

            # -- tick lateness holding (trajectory mode)
            def p99s(seconds):
                mark = driver.planner.diagnostics.mark()
                driver.sleep(seconds)
                driver.sleep(1.2)
                values = [status_values(s) for s in driver.planner.diagnostics.statuses(
                    'crane_streamer: stream', after=mark)]
                return [float(v['lateness_p99_us']) for v in values if 'lateness_p99_us' in v]

            # -- operator mode
            driver.set_parameters('streamer', {'mode': 'operator', 'operator_shaper': 'zv'})
            publisher = driver.node.create_publisher(Twist, CMD_VEL_TOPIC, 10)
            driver.sleep(0.5)
            driver.keep_references()

            def send(vx):
                msg = Twist()
                msg.linear.x = float(vx)
                t = driver.now_ns()
                publisher.publish(msg)
                return t

            delays = []
            for k in range(args.commands):
                sent = send(0.1 if k % 2 == 0 else 0.0)  # on, off: each changes the reference at once
                driver.sleep(0.6)
                refs = np.array(driver.references()[-2000:], dtype=float)
                after = refs[refs[:, 0] >= sent - 2e6]
                changed = np.nonzero(np.abs(np.diff(after[:, 3])) > 1e-12)[0]  # the acceleration moves first
                first = after[changed[0] + 1] if changed.size else np.full(5, np.nan)
                delays.append(((first[0] - sent) * 1e-6, (first[4] - sent) * 1e-6))
            # lateness while the stick moves the crane to and fro
            import threading
            stop = threading.Event()

            def stick(speed=0.15):
                k = 0
                while not stop.is_set():
                    for _ in range(40):
                        msg = Twist()
                        msg.linear.x = speed if k % 2 == 0 else -speed
                        publisher.publish(msg)
                        time.sleep(0.05)
                    k += 1

            driver.keep_references(False)
            send(0.0)
            driver.sleep(2.5)
            driver.wait_until(lambda: _at_rest(driver), 10.0, 'the crane never came to rest')
            # alternating windows, holding in trajectory mode and moving in operator mode, so a shared
            # machine's slow drift falls on both alike
            holding, messages, operating = [], [], []
            for _ in range(args.rounds):
                driver.set_parameters('streamer', {'mode': 'trajectory'})
                holding += p99s(args.window)
                # the same with cmd_vel at 20 Hz (ignored in trajectory mode): what the messages alone cost
                stop.clear()
                thread = threading.Thread(target=stick, args=(0.0,), daemon=True)
                thread.start()
                messages += p99s(args.window)
                stop.set()
                thread.join()
                driver.set_parameters('streamer', {'mode': 'operator'})
                stop.clear()
                thread = threading.Thread(target=stick, daemon=True)
                thread.start()
                operating += p99s(args.window)
                stop.set()
                thread.join()
                send(0.0)
                driver.sleep(2.5)
                driver.wait_until(lambda: _at_rest(driver), 10.0, 'the crane never came to rest')
            d = np.array(delays)
            result['operator_command_to_sample'] = {
                # by the changed sample's stamp (the tick it is due at, its nominal time), and by its arrival
                # here (the way back included: an upper bound)
                'stamp_median_ms': round(float(np.nanmedian(d[:, 0])), 3),
                'stamp_max_ms': round(float(np.nanmax(d[:, 0])), 3),
                'received_median_ms': round(float(np.nanmedian(d[:, 1])), 3),
                'received_p90_ms': round(float(np.nanpercentile(d[:, 1], 90)), 3),
                'received_max_ms': round(float(np.nanmax(d[:, 1])), 3), 'n': int(np.isfinite(d[:, 1]).sum()),
                'target_ms': 2.0, 'shaper_delay_ms': 0.0}
            result['tick_lateness_p99_us'] = {
                'windows_s': args.window, 'per_mode': len(holding),
                'holding_median': round(float(np.median(holding)), 1),
                'holding_with_cmd_vel_20hz_median': round(float(np.median(messages)), 1),
                'operator_median': round(float(np.median(operating)), 1),
                'ratio': round(float(np.median(operating) / np.median(holding)), 2),
                'ratio_to_holding_with_cmd_vel': round(float(np.median(operating) / np.median(messages)), 2)}
        finally:
            driver.close()
            rclpy.try_shutdown()
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
