"""benchmarks/bare_table_benchmark.py: bare tables seen by the rigs of other pools."""

import subprocess
import sys
from pathlib import Path

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
