#!/usr/bin/env bash
# The main job: the whole chain on the bundled bag and the simulated gantry.
# Sets everything up if missing, then runs chain/demo.py (options: --help).
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
"$root/scripts/setup.sh"
# shellcheck disable=SC1091
source "$root/scripts/env.sh"
cd "$root"
exec python -m chain.demo "$@"
