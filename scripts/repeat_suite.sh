#!/usr/bin/env bash
# Zero flakes: run the README's test command N times in a row (default 20) and stop at the
# first failure. Prints one line per run and a summary; exit status 0 only if every run passed.
#   bash scripts/repeat_suite.sh 20 2>&1 | tee flake-run.log
#   bash scripts/repeat_suite.sh 10 2      # the same with 2 CPU-bound programs beside it
# The second argument, BUSY (default 0), starts that many CPU-bound loops (one Python process
# each, `while True: pass`) for the loop's whole length, as a laptop busy with other work.
set -u
n="${1:-20}"
busy="${2:-0}"
cd "$(dirname "$0")/.."
py="${PYTEST:-.venv/bin/pytest}"
hogs=()
stop_hogs() { [ "${#hogs[@]}" -gt 0 ] && kill "${hogs[@]}" 2>/dev/null; }
trap stop_hogs EXIT
for _ in $(seq 1 "$busy"); do
  python3 -c 'while True: pass' &
  hogs+=("$!")
done
[ "$busy" -gt 0 ] && echo "with $busy CPU-bound programs beside it (pids ${hogs[*]})"
for i in $(seq 1 "$n"); do
  start=$(date +%s)
  out=$("$py" -q -p no:cacheprovider 2>&1)
  rc=$?
  summary=$(printf '%s\n' "$out" | tail -1)
  echo "run $i/$n: status $rc, $(( $(date +%s) - start )) s: $summary"
  if [ "$rc" -ne 0 ]; then
    printf '%s\n' "$out" | grep -E "^(FAILED|ERROR)" >&2
    log="${TMPDIR:-/tmp}/repeat_suite_run$i.log"
    printf '%s\n' "$out" > "$log"
    echo "the whole output of run $i is in $log" >&2
    echo "FLAKE OR FAILURE at run $i of $n"
    exit 1
  fi
done
echo "all $n runs passed"
