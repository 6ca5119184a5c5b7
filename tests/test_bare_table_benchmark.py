"""benchmarks/bare_table_benchmark.py: bare tables seen by the rigs of other pools."""

import dataclasses
import subprocess
import sys
from pathlib import Path

import numpy as np

from benchmarks import bare_table_benchmark

ROOT = Path(__file__).resolve().parents[1]


def _run(*arguments: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, str(ROOT / 'benchmarks' / 'bare_table_benchmark.py'),
                           *arguments], capture_output=True, text=True, timeout=120)


def test_the_evaluation_split_keeps_its_held_out_rigs():
    result = _run('--rig-pool-seed', '15')
    assert result.returncode == 2
    assert '--rig-pool-seed' in result.stderr and 'evaluation split' in result.stderr


def test_a_pool_seed_writes_a_report_of_its_own(tmp_path):
    result = _run('--split', 'train', '--rig-pool-seed', '15', '--per-type', '1',
                  '--point-stride', '3', '--output', str(tmp_path))
    assert result.returncode == 0, result.stderr
    report = (tmp_path / 'bare_tables_train_pool15.md').read_text()
    assert 'of 4 |' in report  # one bare table per object type


def test_a_cache_gives_the_same_tables_back_without_rendering_them_again(tmp_path,
                                                                           monkeypatch):
    rendered = []
    render = bare_table_benchmark.match_scene

    def counted(scene, strides, **options):
        rendered.append(scene.seed)
        return render(scene, strides, **options)

    monkeypatch.setattr(bare_table_benchmark, 'match_scene', counted)
    settings = dataclasses.replace(bare_table_benchmark.DEFAULT_SETTINGS, rig_pool_seed=15)

    def tables():
        return list(bare_table_benchmark.matched_tables('train', 1, [3], settings, tmp_path))

    first = tables()
    assert len(rendered) == 4 and len(first) == 4  # one bare table per object type
    assert [path.name for path in tmp_path.iterdir()] == [
        'bare_tables_train_1_stride3_pool15.pickle']
    second = tables()
    assert len(rendered) == 4  # read back, not rendered again
    assert [table.scene.seed for table in second] == [table.scene.seed for table in first]
    for before, after in zip(first, second, strict=True):
        assert np.array_equal(before.matched[3].points.u_right,
                              after.matched[3].points.u_right)
