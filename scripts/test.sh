#!/usr/bin/env bash
# Run every test: set-up if missing, lint, then pytest over tests/ and each package's test/.
# Extra arguments go to pytest (for example: scripts/test.sh -k fuzzy -x).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/setup.sh"
# shellcheck disable=SC1091
source "$root/scripts/env.sh"
cd "$root"
echo '[test] ruff check'
ruff check .
echo '[test] mypy'
mypy
echo '[test] pytest'
python -m pytest "$@"
