"""crane-teleop's script and options (the ROS side runs in test/ros/test_operator.py)."""
import pytest

from crane_planner.tools.teleop import main, parse_script


def test_a_script_is_segments_of_stick_positions_and_seconds():
    assert parse_script('0.2:3 0.2,0.05:1.5 0:2') == [(0.2, 0.0, 0.0, 3.0), (0.2, 0.0, 0.05, 1.5),
                                                      (0.0, 0.0, 0.0, 2.0)]
    # three values: the bridge's too (cmd_vel linear.x, linear.y, linear.z)
    assert parse_script('0.2,-0.15,0.05:2') == [(0.2, -0.15, 0.05, 2.0)]


@pytest.mark.parametrize('script, reason', [('', 'no segment'), ('0.2', 'bad script segment'),
                                            ('0.2:0', 'duration > 0'), ('nan:1', 'finite'),
                                            ('0.1,0.2,0.3,0.4:1', 'bad script segment')])
def test_bad_scripts_are_one_line_and_exit_2(capsys, script, reason):
    assert main(['--script', script]) == 2
    err = capsys.readouterr().err
    assert err.count('\n') == 1 and err.startswith('crane-teleop: error:') and reason in err


def test_a_bad_rate_exits_2(capsys):
    assert main(['--script', '0.1:1', '--rate', '0']) == 2
    assert '--rate' in capsys.readouterr().err
