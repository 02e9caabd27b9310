#!/usr/bin/env bash
# Sets up everything this project needs, idempotently:
#   1. .venv with every dependency pinned in requirements.lock (real ROS 2 Jazzy wheels),
#   2. the CMake path fix for the wheels' exported include paths,
#   3. `colcon build` of src/ into build/ and install/.
# Each step is skipped when its inputs have not changed (a stamp holds their hash), so a
# second run with nothing changed takes a couple of seconds.
set -euo pipefail
root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$root"
venv="$root/.venv"
say() { printf '[setup] %s\n' "$*"; }
die() { printf '[setup] error: %s\n' "$*" >&2; exit 1; }

# --- prerequisites ---------------------------------------------------------------
missing=()
command -v python3 >/dev/null || missing+=("python3 (3.11, with venv: apt-get install python3 python3-venv python3-dev)")
command -v cmake >/dev/null || missing+=("cmake (>= 3.22: apt-get install cmake)")
command -v cc >/dev/null || command -v gcc >/dev/null || missing+=("a C compiler (apt-get install build-essential)")
command -v c++ >/dev/null || command -v g++ >/dev/null || missing+=("a C++ compiler (apt-get install build-essential)")
if ((${#missing[@]})); then
  list=$(printf '%s; ' "${missing[@]}")
  die "missing prerequisites, please install: ${list%; }"
fi
pyver=$(python3 -c 'import sys; print("%d.%d" % sys.version_info[:2])')
[[ "$pyver" == "3.11" ]] || die "python3 is $pyver; the ROS 2 Jazzy wheels need Python 3.11 (put a python3.11 first on PATH)"

hash_of() { cat "$@" | sha256sum | cut -d' ' -f1; }

# --- 1. virtual environment ---------------------------------------------------------
lock_hash=$(hash_of requirements.lock)
if [[ ! -x "$venv/bin/python" ]] || [[ "$(cat "$venv/.lock-hash" 2>/dev/null)" != "$lock_hash" ]]; then
  say "installing pinned dependencies into .venv (first run: about a minute)"
  [[ -x "$venv/bin/python" ]] || python3 -m venv "$venv" || die "python3 -m venv failed (apt-get install python3-venv)"
  "$venv/bin/pip" install --quiet --disable-pip-version-check -r requirements.lock \
    || die "pip install -r requirements.lock failed (see above)"
  echo "$lock_hash" > "$venv/.lock-hash"
  rm -f "$root/install/.src-hash"   # new wheels: rebuild the workspace
else
  say ".venv up to date"
fi

# --- 2. CMake path fix --------------------------------------------------------------
# The wheels' CMake exports hard-code the wheel builder's Python and numpy include
# directories; point them at this interpreter's. Idempotent: fixed files no longer match.
"$venv/bin/python" - <<'PY'
import pathlib, sysconfig, numpy
fixes = {
    "/opt/python/cp311-cp311/lib/python3.11/site-packages/numpy/_core/include": numpy.get_include(),
    "/opt/python/cp311-cp311/include/python3.11": sysconfig.get_paths()["include"],
}
share = pathlib.Path(__import__("sys").prefix) / "share"
n = 0
for path in share.rglob("*.cmake"):
    text = path.read_text()
    if "/opt/python/cp311-cp311/" in text:
        for old, new in fixes.items():
            text = text.replace(old, new)
        path.write_text(text)
        n += 1
if n:
    print(f"[setup] fixed wheel include paths in {n} CMake files")
PY

# --- 3. colcon build ---------------------------------------------------------------
src_hash=$( (find src config cmake -type f -not -path '*/__pycache__/*' -not -name '*.pyc' | LC_ALL=C sort | xargs sha256sum) | sha256sum | cut -d' ' -f1)
if [[ "$(cat install/.src-hash 2>/dev/null)" != "$src_hash" ]]; then
  say "colcon build (src/ changed)"
  (
    # shellcheck disable=SC1091
    source "$venv/bin/activate"
    # pinocchio's, Eigen's and urdfdom's CMake configs sit in the wheels' cmeel prefix.
    export AMENT_PREFIX_PATH="$venv" CMAKE_PREFIX_PATH="$venv:$("$venv/bin/python" -m cmeel cmake)"
    colcon --log-base log build --base-paths src --event-handlers console_cohesion- \
      --cmake-args -DBUILD_TESTING=OFF -DPython3_EXECUTABLE="$venv/bin/python" -DPython_EXECUTABLE="$venv/bin/python"
  ) > build.log 2>&1 || { tail -40 build.log >&2; die "colcon build failed (full log: build.log)"; }
  echo "$src_hash" > install/.src-hash
else
  say "workspace up to date"
fi
say "ready: source env.sh"
