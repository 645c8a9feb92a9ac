#!/usr/bin/env bash
# Instructions per compute of two builds of vfe (e.g. before and after a change), counted by
# callgrind, so the comparison does not depend on what else the machine is doing. Per method
# on the Cartesian grid: `vfe bench` (2e4 particles, chi = 2, one thread, pmm at 45
# sub-elements) with 3 and with 1 timed repeats, halved difference: scene generation and
# set-up cancel. Usage: scripts/compare_builds.sh BEFORE_BUILD_DIR AFTER_BUILD_DIR
set -euo pipefail
before=$1 after=$2
ir() {  # build repeats method
  LD_LIBRARY_PATH="$1/engine" valgrind --tool=callgrind --callgrind-out-file=/dev/null "$1/vfe" bench \
    --particles 2e4 --chi 2 --threads 1 --repeats "$2" --no-limits --method "$3" --particle-grid 45 -q \
    -o "$(mktemp -d)" 2>&1 | sed -n 's/.*Collected : \([0-9]*\).*/\1/p'
}
echo "method,before_instructions_per_compute,after_instructions_per_compute,ratio"
for m in direct pmm exact divided gaussian porous_cube big_particle trilinear; do
  b1=$(ir "$before" 1 $m); b3=$(ir "$before" 3 $m); a1=$(ir "$after" 1 $m); a3=$(ir "$after" 3 $m)
  awk -v m=$m -v b1="$b1" -v b3="$b3" -v a1="$a1" -v a3="$a3" \
    'BEGIN { b = (b3 - b1) / 2; a = (a3 - a1) / 2; printf "%s,%d,%d,%.3f\n", m, b, a, a / b }'
done
