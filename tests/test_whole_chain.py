"""Replay each committed bag through the whole chain: every node a process, the simulated
gantry on a pseudo-terminal, as the demo runs it (chain/demo.py)."""

from pathlib import Path

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.system]

REPO_ROOT = Path(__file__).resolve().parents[1]
BAGS = sorted(path for path in (REPO_ROOT / 'bags').iterdir()
              if (path / 'metadata.yaml').exists())


def test_committed_bags_exist():
    names = {bag.name for bag in BAGS}
    assert 'demo_scenes' in names, f'bags/ holds {sorted(names)}'


@pytest.mark.parametrize('bag', BAGS, ids=[bag.name for bag in BAGS])
def test_bag_through_the_whole_chain(ros_domain_id, tmp_path, bag):
    from chain.demo import DEFAULT_PARAMS, DEMO_TOLERANCE_MM, DemoRun, format_table

    run = DemoRun(bag, DEFAULT_PARAMS, tmp_path / 'demo', DEMO_TOLERANCE_MM, rate=0.5,
                  timeout_s=300.0, quiet=True)
    results = run.run()
    table = format_table(results)

    assert results, 'no object with ground truth was seen: the bag did not play'
    for result in results:
        assert result.best_point is not None, f'object {result.index}: {result.status}\n{table}'
        assert result.error_mm <= DEMO_TOLERANCE_MM, (
            f'object {result.index} best point {result.error_mm:.2f} mm from its ground truth '
            f'(tolerance {DEMO_TOLERANCE_MM} mm)\n{table}')
        assert result.final_position is not None, (
            f'object {result.index}: the gantry was never Idle at {result.commanded}\n{table}')
        assert result.gcode_lines, f'object {result.index}: no G-code was sent for it\n{table}'

    sent = run.sent_log.read_text().splitlines()
    received = run.received_log.read_text().splitlines()
    assert sent == received, (
        'the G-code the simulator received differs from what the driver sent:\n'
        f'sent {len(sent)} lines, received {len(received)}')

    errors = {process.name: process.error_lines() for process in run.group.processes}
    assert not any(errors.values()), f'nodes logged errors: {errors}'
    assert all(code == 0 for code in run.exit_codes.values()), (
        f'processes did not exit cleanly: {run.exit_codes}')
    pictures = sorted((tmp_path / 'demo').glob('object_*.png'))
    assert len(pictures) == len(results), 'a picture per object was expected'
