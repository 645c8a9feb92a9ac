#!/usr/bin/env bash
# Builds the libFuzzer targets (clang, ASan + UBSan) in build/fuzz and fuzzes each for
# SECONDS (default 25) from the seeds in tests/fuzz/corpus and data/. Fails when a target
# crashes; the crashing input is left in build/fuzz/artifacts/<target>/ (keep it in
# tests/fuzz/corpus/<target>/ once fixed, so the release tests replay it).
#   tests/fuzz/run_fuzz.sh [SECONDS] [TARGET ...]
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${1:-25}
shift || true
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(polymesh shapes dump scene_config options)

sudo_if_needed() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
fuzzer_lib=$(clang -print-file-name=libclang_rt.fuzzer-x86_64.a 2>/dev/null || true)
if ! command -v clang++ >/dev/null || [ ! -f "$fuzzer_lib" ]; then
  sudo_if_needed apt-get update -qq
  sudo_if_needed env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends clang libclang-rt-dev
fi

build=build/fuzz
cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_C_FLAGS="-O1 -g -fsanitize=fuzzer-no-link" -DCMAKE_CXX_FLAGS="-O1 -g -fsanitize=fuzzer-no-link" \
  -DVFE_SANITIZE=ON -DVFE_FUZZ=ON -DVFE_BUILD_BENCHMARKS=OFF >/dev/null
cmake --build "$build" -j2 --target "${targets[@]/#/fuzz_}"

# Seeds from data/ as well as the hand-made ones (each target reads only what it knows).
seeds=$build/seeds
rm -rf "$seeds" && mkdir -p "$seeds"/{shapes,dump,scene_config}
for f in data/shapes/*.obj; do { printf '\001'; cat "$f"; } >"$seeds/shapes/$(basename "$f")"; done
{ printf '\000'; cat data/shapes/mixed_shapes.dump; } >"$seeds/dump/mixed_shapes"
{ printf '\000'; gzip -dc data/liggghts/bed_mono_final.dump.gz | head -n 60 || true; } >"$seeds/dump/liggghts_head"  # gzip stops on SIGPIPE
cp configs/*.yaml "$seeds/scene_config/"

status=0
export ASAN_OPTIONS=detect_leaks=0:allocator_may_return_null=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
for t in "${targets[@]}"; do
  work=$build/corpus/$t artifacts=$build/artifacts/$t
  mkdir -p "$work" "$artifacts"
  extra=()
  [ -d "$seeds/$t" ] && extra=("$seeds/$t")
  echo "== fuzz_$t for ${seconds}s"
  if ! "$build/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -max_len=65536 -timeout=20 -rss_limit_mb=2048 \
      -artifact_prefix="$artifacts/" -print_final_stats=1 "$work" "tests/fuzz/corpus/$t" "${extra[@]}" \
      >"$build/fuzz_$t.log" 2>&1; then
    echo "fuzz_$t FAILED: see $build/fuzz_$t.log and $artifacts/"
    tail -n 40 "$build/fuzz_$t.log"
    status=1
  fi
  grep -E "stat::number_of_executed_units|stat::peak_rss_mb" "$build/fuzz_$t.log" | sed "s/^/  fuzz_$t /" || true
done
exit $status
