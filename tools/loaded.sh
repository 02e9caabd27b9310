#!/usr/bin/env bash
# Run a command beside CPU-bound burners, one per core: the machine a busy CI runner is.
#
#   tools/loaded.sh COMMAND [ARG...]      (make test-loaded: the pytest suite this way)
#
# LOADED_BURNERS=N: N burners instead of `nproc`. LOADED_PIDS_FILE=PATH: their process ids written
# there, one a line, before COMMAND starts (test/test_loaded.py checks they ran and are gone).
# The burners are stopped when this script ends, however it ends: COMMAND's exit, a signal (the trap),
# or even SIGKILL (each burner checks between busy rounds that this script is still alive).
# Exits with COMMAND's status.
set -uo pipefail

if [ $# -eq 0 ]; then
  echo "usage: tools/loaded.sh COMMAND [ARG...]" >&2
  exit 2
fi

count="${LOADED_BURNERS:-$(nproc)}"
parent=$$
burners=()

stop_burners() {
  if [ ${#burners[@]} -gt 0 ]; then
    kill "${burners[@]}" 2>/dev/null
    wait "${burners[@]}" 2>/dev/null
  fi
  burners=()
}
trap stop_burners EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

for _ in $(seq "$count"); do
  # Pure computation (builtins only, no system call but the liveness check every ~20k rounds).
  ( while kill -0 "$parent" 2>/dev/null; do for ((i = 0; i < 20000; i++)); do :; done; done ) &
  burners+=("$!")
done
if [ -n "${LOADED_PIDS_FILE:-}" ]; then
  printf '%s\n' "${burners[@]}" >"$LOADED_PIDS_FILE"
fi
echo "[loaded] ${count} CPU-bound burner(s) beside: $*" >&2

# In the foreground: a Ctrl-C reaches it as it would without the burners (the INT trap runs once it ends).
"$@"
exit $?
