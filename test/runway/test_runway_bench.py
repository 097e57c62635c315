"""bench/runway.py on 20 of its seeded scenarios (the benchmark runs 1,000): no two cranes ever closer than the
minimum distance by its dense check, the moves together within 1.15x of each crane alone, and sooner than by the
anchors' rule on the same moves, which waits where planning around the others does not."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

_spec = importlib.util.spec_from_file_location('runway_bench', Path(__file__).parents[2] / 'bench' / 'runway.py')
bench = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(bench)


@pytest.fixture(scope='module')
def result():
    return bench.scenarios(20)


def test_twenty_scenarios_keep_the_distance_take_little_longer_than_alone_and_beat_the_anchors_rule(result):
    assert result['scenarios'] == 20 and result['refused_moves'] == result['anchors_refused_moves'] == 0
    assert result['vs_alone']['scenarios'] == result['vs_anchors']['scenarios'] == 20
    assert result['cranes'] == {2: 7, 3: 6, 4: 7}
    # (a) checked every millisecond on the moves' masses predicted again, not on the samples the schedule used
    assert result['violations'] == 0 and result['dense_min_m'] >= bench.MIN_DISTANCE
    # (b) one move did have to wait for another (the check is not vacuous), and the total stayed within 1.15x
    assert result['delayed_moves'] >= 1
    assert result['vs_alone']['ratio'] <= 1.15
    # (c) the anchors' rule waited more often, and took longer in all
    assert result['anchors_delayed_moves'] > result['delayed_moves']
    assert result['vs_anchors']['total_s'] < result['vs_anchors']['anchors_s']
    assert result['vs_anchors']['longer'] == 0


def test_the_scenarios_are_seeded_and_keep_the_cranes_order_and_their_rest_gaps():
    a, b = bench.draw(7), bench.draw(7)
    assert a == b and bench.draw(7, seed=1) != a
    for k in range(50):
        s = bench.draw(k)
        ys = [c.offset[1] for c in s.cranes]
        goals = [c.offset[1] + m.goal['bridge'] for c, m in zip(s.cranes, s.moves)]
        assert 2 <= len(ys) <= 4 and np.all(np.diff(ys) >= 0.6 - 1e-9)
        assert np.all(np.diff(goals) >= bench.REST_GAP - 1e-9)  # the order kept, the goals apart
        assert all(abs(m.goal['bridge']) >= 0.2 - 1e-9 and m.method in bench.METHODS for m in s.moves)
