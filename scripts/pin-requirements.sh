#!/usr/bin/env bash
# Resolve requirements.in in a scratch venv and write the exact pins to requirements.txt.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
python3.11 -m venv "$scratch/venv"
"$scratch/venv/bin/pip" install -q --upgrade pip
"$scratch/venv/bin/pip" install -q -r "$root/requirements.in"
{
  echo '# Exact pins of requirements.in and everything it pulls in (scripts/pin-requirements.sh).'
  # Only real distributions: the ROS wheels also carry their packages' own *.egg-info metadata,
  # which pip freeze lists but PyPI does not have.
  "$scratch/venv/bin/python" - <<'PY'
from importlib.metadata import distributions
pins = {d.metadata['Name']: d.version for d in distributions() if str(d._path).endswith('.dist-info')}
for name in sorted(pins, key=str.lower):
    if name.lower() not in ('pip', 'setuptools', 'wheel'):
        print(f'{name}=={pins[name]}')
PY
} > "$root/requirements.txt"
