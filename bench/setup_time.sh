#!/usr/bin/env bash
# Fresh-clone time to a built, checked workspace: clones this repository into a temporary
# directory and times ./setup.sh there (first run = fresh clone, second run = re-run).
# Prints the two wall-clock times. The pip cache is whatever the machine has (warm after a
# first setup). Usage: bash bench/setup_time.sh
set -Eeuo pipefail
ROOT=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
dir=$(mktemp -d)
trap 'rm -rf "$dir"' EXIT
git clone -q "$ROOT" "$dir/c4d"
cd "$dir/c4d"
t0=$(date +%s.%N)
./setup.sh > "$dir/first.log" 2>&1 || { tail -3 "$dir/first.log"; exit 1; }
t1=$(date +%s.%N)
./setup.sh > "$dir/second.log" 2>&1 || { tail -3 "$dir/second.log"; exit 1; }
t2=$(date +%s.%N)
printf 'setup_time: fresh clone -> built workspace: %.1f s\n' "$(echo "$t1 - $t0" | bc)"
printf 'setup_time: second run (idempotent):        %.1f s\n' "$(echo "$t2 - $t1" | bc)"
