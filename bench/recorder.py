"""crane-record beside the streamer and the sim: what it keeps of the 1 kHz reference, and its CPU.

Starts the real streamer (holding: it publishes every tick all the same) and
sim executables in a private ROS graph, then ``crane-record --duration S`` of
``reference`` and ``joint_states`` as a process. What it kept is counted from
the recording: the reference's header stamps, one per tick on the streamer's
1 ms grid, against every tick between the first and the last recorded one
(the streamer publishes each; a skipped tick would be in its timing log).
CPU is the recorder's utime + stime (its rusage at exit) over its run.

Targets: >= 99 % of the reference samples published while it recorded (a recording
that misses more is no record of the run), and no more than 25 % of a core for
the recorder.

    .venv/bin/python bench/recorder.py [--duration 20]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument('--duration', type=float, default=20.0, help='recorded seconds (default 20)')
    args = ap.parse_args()
    from crane_planner.tools.processes import isolated_graph
    with isolated_graph() as env:
        return measure(args, env)


def measure(args, env: dict) -> int:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    from crane_planner.tools.processes import SIM, STREAMER, NodeGroup, find_executable

    ns = '/bench_record'
    workdir = Path(tempfile.mkdtemp(prefix='recorder-bench-'))
    timing_log, bag = workdir / 'timing.json', workdir / 'bag'
    with NodeGroup(env, workdir) as nodes:
        nodes.start(*STREAMER, namespace=ns, params={'timing_log': str(timing_log)})
        nodes.start(*SIM, namespace=ns)
        time.sleep(3.0)
        nodes.check_alive()
        recorder = subprocess.Popen([find_executable('crane_planner', 'crane-record'), '--namespace', ns,
                                     '--topics', 'reference,joint_states', '--out', str(bag),
                                     '--duration', str(args.duration)],
                                    env=env, stderr=subprocess.PIPE, text=True)
        _, status, usage = os.wait4(recorder.pid, 0)
        recorder.returncode = os.waitstatus_to_exitcode(status)
        log = recorder.stderr.read().strip().splitlines()
        nodes.check_alive()
    if recorder.returncode != 0:
        print(json.dumps({'error': log[-1] if log else f'exit {recorder.returncode}'}))
        return 1
    [mcap_file] = bag.glob('*.mcap')
    stamps = []
    with open(mcap_file, 'rb') as f:
        for _, channel, _, ros in make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages():
            if channel.topic.endswith('/reference'):
                stamps.append(ros.header.stamp.sec * 10**9 + ros.header.stamp.nanosec)
    # the streamer's ticks are first_tick_ns + k ms; those between the first and the last recorded one
    ticks = json.loads(timing_log.read_text())
    first, last = min(stamps), max(stamps)
    published = (last - first) // 1_000_000 + 1
    kept = len(set(stamps))
    cpu = usage.ru_utime + usage.ru_stime
    result = {
        'duration_s': args.duration,
        'reference': {'published': int(published), 'recorded': kept, 'kept_pct': round(100.0 * kept / published, 3),
                      'streamer_late_ticks_over_1ms': int(sum(x > 1000.0 for x in ticks['lateness_us']))},
        'recorder': {'cpu_pct_of_core': round(100.0 * cpu / args.duration, 1), 'max_rss_mb': usage.ru_maxrss // 1024,
                     'summary': log[-1]},
    }
    result['targets_met'] = result['reference']['kept_pct'] >= 99.0 and result['recorder']['cpu_pct_of_core'] <= 25.0
    print(json.dumps(result))
    return 0


if __name__ == '__main__':
    sys.exit(main())
