"""crane-teleop: a joystick for people without one: the keyboard or a script of stick positions on cmd_vel.

Publishes ``geometry_msgs/Twist`` on ``cmd_vel`` (in ``--namespace``) at
``--rate``: ``linear.x`` the cart's velocity (m/s), ``linear.y`` the
bridge's (m/s), ``linear.z`` the load's vertical velocity (m/s, + = up), what
the streamer follows in its operator
mode (``mode: operator``). With ``--script`` it plays stick positions and
exits; the keyboard (the default, on a terminal) sets the stick until the
next key. When the tool stops publishing, the streamer counts the command
as zero after its ``cmd_timeout`` and brings the crane to rest, shaped.

Script: segments ``VX[,VZ]:SECONDS`` or ``VX,VY,VZ:SECONDS`` (with a bridge)
separated by spaces, e.g. ``"0.2:1 0.2,0.05:2 0:3"`` (forward, forward while
lifting, release) or ``"0.2,0.15,0:2 0:3"`` (diagonal, release); a script
starting with a minus sign is given as ``--script=-0.2:3``.
Keys: a/d or left/right move the cart by --speed, j/l the bridge by --speed,
w/s or up/down raise or lower the load by --hoist-speed, space releases the
stick, q quits.
Exit 0; 1 if nothing subscribes to cmd_vel within ``--wait``; 2 on bad options (one line on stderr).
"""
from __future__ import annotations

import argparse
import math
import sys
import time

PROG = 'crane-teleop'
#: Seconds of a released stick a script starts with, once the streamer subscribes.
PRIME = 0.5

#: Keys (and arrow-key escape sequences) -> (stick axis: 0 cart x, 1 bridge y, 2 load z; direction); None releases.
KEYS = {'a': (0, -1), 'd': (0, 1), 'j': (1, -1), 'l': (1, 1), 'w': (2, 1), 's': (2, -1), '\x1b[D': (0, -1),
        '\x1b[C': (0, 1), '\x1b[A': (2, 1), '\x1b[B': (2, -1), ' ': None}


def parse_script(text: str) -> list[tuple[float, float, float, float]]:
    """Segments (cart m/s, bridge m/s, load m/s, seconds) of a script (see the module docstring); ValueError names
    the bad one."""
    segments = []
    for part in text.split():
        try:
            stick, seconds = part.split(':')
            values = [float(x) for x in stick.split(',')]
            if not 1 <= len(values) <= 3:
                raise ValueError
            duration = float(seconds)
        except ValueError:
            raise ValueError(f'bad script segment {part!r}: write VX[,VZ]:SECONDS or VX,VY,VZ:SECONDS, '
                             f'e.g. 0.2,0.05:2') from None
        if not all(math.isfinite(x) for x in values) or not (math.isfinite(duration) and duration > 0.0):
            raise ValueError(f'bad script segment {part!r}: finite velocities and a duration > 0 s')
        x, y, z = values if len(values) == 3 else (values[0], 0.0, values[1] if len(values) > 1 else 0.0)
        segments.append((x, y, z, duration))
    if not segments:
        raise ValueError('the script has no segment')
    return segments


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog=PROG, description=__doc__.splitlines()[0].split(': ', 1)[1])
    p.add_argument('--namespace', default='/', help='namespace of the streamer (default /)')
    p.add_argument('--script', metavar='"VX[,VZ]:S | VX,VY,VZ:S ..."',
                   help='play these stick positions and exit (default: the keyboard)')
    p.add_argument('--rate', type=float, default=20.0, help='publishing rate (Hz, default 20)')
    p.add_argument('--wait', type=float, default=10.0, metavar='S',
                   help='seconds to wait for the streamer to subscribe before a script plays (default 10)')
    p.add_argument('--speed', type=float, default=0.2,
                   help='keyboard: the cart\'s and the bridge\'s speed of a key (m/s, default 0.2)')
    p.add_argument('--hoist-speed', type=float, default=0.1,
                   help='keyboard: the load speed of a key (m/s, default 0.1)')
    return p


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    try:
        segments = parse_script(args.script) if args.script is not None else None
        if not (math.isfinite(args.rate) and 0.0 < args.rate <= 1000.0):
            raise ValueError(f'--rate must be in (0, 1000] Hz, got {args.rate}')
        if segments is None and not sys.stdin.isatty():
            raise ValueError('the keyboard needs a terminal: run it in one, or give --script')
    except ValueError as exc:
        print(f'{PROG}: error: {exc}', file=sys.stderr)
        return 2
    import rclpy
    from geometry_msgs.msg import Twist
    from rclpy.signals import SignalHandlerOptions

    from crane_msgs_py.messages.names import CMD_VEL_TOPIC
    from crane_msgs_py.runtime.realtime import die_with_parent
    die_with_parent()
    rclpy.init(signal_handler_options=SignalHandlerOptions.NO)
    node = rclpy.create_node('crane_teleop', namespace=args.namespace, start_parameter_services=False)
    publisher = node.create_publisher(Twist, CMD_VEL_TOPIC, 10)
    period = 1.0 / args.rate

    def publish(cart: float, bridge: float, load: float):
        msg = Twist()
        msg.linear.x, msg.linear.y, msg.linear.z = float(cart), float(bridge), float(load)
        publisher.publish(msg)

    try:
        if segments is not None:
            # a script plays from the moment the streamer hears it: its durations are the crane's
            deadline = time.monotonic() + args.wait
            while publisher.get_subscription_count() == 0:
                if time.monotonic() > deadline:
                    print(f'{PROG}: error: nothing subscribes to {node.resolve_topic_name(CMD_VEL_TOPIC)} within '
                          f'{args.wait:g} s (is the streamer running in this namespace?)', file=sys.stderr)
                    return 1
                time.sleep(0.01)
            # a released stick first, until the subscriber has surely matched too (a few hundred ms
            # after the publisher sees it): the first segment is then heard from its start
            end = time.monotonic() + PRIME
            while time.monotonic() < end:
                publish(0.0, 0.0, 0.0)
                time.sleep(period)
            print(f'{PROG}: playing {len(segments)} segment(s) on {node.resolve_topic_name(CMD_VEL_TOPIC)}',
                  file=sys.stderr)
            for *stick, seconds in segments:
                end = time.monotonic() + seconds
                while time.monotonic() < end:
                    publish(*stick)
                    time.sleep(min(period, max(0.0, end - time.monotonic())))
            publish(0.0, 0.0, 0.0)
            return 0
        return _keyboard(publish, period, args.speed, args.hoist_speed)
    except KeyboardInterrupt:
        return 0
    finally:
        try:
            publish(0.0, 0.0, 0.0)
        except Exception:
            pass
        node.destroy_node()
        rclpy.try_shutdown()


def _keyboard(publish, period: float, speed: float, hoist_speed: float) -> int:
    """The keyboard loop: a key sets the stick until the next one."""
    import select
    import termios
    import tty
    fd = sys.stdin.fileno()
    saved = termios.tcgetattr(fd)
    stick = [0.0, 0.0, 0.0]
    speeds = (speed, speed, hoist_speed)
    print(f'{PROG}: a/d or arrows move the cart, j/l the bridge, w/s or arrows the load, space releases, q quits',
          file=sys.stderr)
    try:
        tty.setcbreak(fd)
        while True:
            if select.select([sys.stdin], [], [], period)[0]:
                key = sys.stdin.read(1)
                if key == '\x1b':  # an arrow: ESC [ X
                    key += sys.stdin.read(2)
                if key in ('q', '\x03'):
                    return 0
                if key in KEYS:
                    if KEYS[key] is None:
                        stick = [0.0, 0.0, 0.0]
                    else:
                        k, direction = KEYS[key]
                        stick[k] = direction * speeds[k]
                    print(f'\r{PROG}: cart {stick[0]:+.2f} m/s, bridge {stick[1]:+.2f} m/s, load {stick[2]:+.2f} m/s  ',
                          end='', file=sys.stderr, flush=True)
            publish(*stick)
    finally:
        termios.tcsetattr(fd, termios.TCSADRAIN, saved)
        print(file=sys.stderr)


if __name__ == '__main__':
    sys.exit(main())
