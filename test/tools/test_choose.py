"""crane-plan choose (crane_planner.tools.choose), through ``cli.main``: the fastest method within the
residual tolerance over the L1 band, the others' reasons, the figure, the refusal."""
import json

import pytest
from crane_plan_cli import crane_plan


def test_choose_marks_the_fastest_method_within_the_tolerance_and_says_why_not_the_others(tmp_path):
    out = crane_plan('choose', '--displacement', '0.3', '--max-velocity', '0.25', '--max-acceleration', '0.5',
                     '--methods', 'zv,zvd,zvdd', '--points', '5', '--tolerance-mm', '1', '--json',
                     '--plot', tmp_path / 'choose.png')
    assert out.returncode == 0, out.stderr
    data = json.loads(out.stdout)
    rows = {m['method']: m for m in data['methods']}
    assert len(data['plants']) == 5 and min(p['L1'] for p in data['plants']) == pytest.approx(0.47 * 0.8)
    chosen = rows[data['chosen']]
    assert chosen['worst_residual_mm'] <= 1.0 and chosen['verdict'].startswith('chosen')
    for row in rows.values():  # every faster method is beyond the tolerance, and says so
        if row['duration'] < chosen['duration']:
            assert row['worst_residual_mm'] > 1.0 and 'exceeds 1 mm' in row['verdict']
    # the worst residual is the band's: ZV, tuned to the nominal L1, leaves far more at L1 -20 %
    assert rows['zv']['worst_residual_mm'] > 10 * min(rows['zv']['residual_mm'])
    assert (tmp_path / 'choose.png').stat().st_size > 10_000
    bad = crane_plan('choose', '--displacement', '0.3')
    assert bad.returncode == 2 and 'needs axis limits' in bad.stderr
