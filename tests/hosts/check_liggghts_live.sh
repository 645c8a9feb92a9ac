#!/usr/bin/env bash
# The live LIGGGHTS driver as vfe run's particle source: `vfe run` starts vfe_liggghts with
# --dump - (4 coupling steps of the pour, each frame printed as it is reached) and computes
# each frame as it comes, with coupling fields; a tee keeps the same frames as a dump file.
# `vfe run` on that file must give the same fields, weights, Us and jumps (every per-frame
# file byte for byte, every report column but the times). A driver that fails stops the run
# naming the command.
# Usage: check_liggghts_live.sh SOURCE_DIR VFE_CLI VFE_LIGGGHTS
set -euo pipefail
src="$1"; cli="$2"; driver="$3"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
couplings=4

scene() {  # scene NAME PARTICLES: a config of the 2 mm grid over the driver's DEM box
  cat >"$work/$1.yaml" <<YAML
name: $1
particles: $2
meshes: [{name: grid, origin: [0, 0, 0], spacing: 0.002, cells: [5, 5, 10]}]
methods: [pmm, {method: pmm, options: "incremental=1", label: pmm_incremental}, exact]
reference: exact
threads: 1
options: "outside=nearest deterministic=1"
output: out_$1
coupling: true
vtk: true
YAML
}
scene live "{command: \"'$driver' --input '$src/hosts/liggghts/in.pour_settle' --every 250 --couplings $couplings --cell 0.002 --dump - --screen liggghts.screen --csv driver.csv | tee live.dump\", dem_dt: 1.0e-5}"
scene files "{file: live.dump, frames: all, dem_dt: 1.0e-5}"

"$cli" run "$work/live.yaml" >"$work/live.txt" 2>"$work/live.log" || { cat "$work/live.log"; exit 1; }
grep -q "frame $couplings (timestep $((250 * couplings))" "$work/live.log" || { cat "$work/live.log"; echo "no progress line of frame $couplings"; exit 1; }
"$cli" run "$work/files.yaml" -q >"$work/files.txt"

rows=$(($(wc -l <"$work/out_live/frames.csv") - 1))
[ "$rows" -eq $((3 * couplings)) ] || { echo "frames.csv has $rows rows, expected $((3 * couplings))"; exit 1; }
# Every report column but the compute times (frames.csv: ms is column 6; frame_jumps.csv:
# ms_median is column 6).
for f in frames.csv frame_jumps.csv; do
  if ! diff <(cut -d, -f1-5,7- "$work/out_live/$f") <(cut -d, -f1-5,7- "$work/out_files/$f"); then
    echo "$f differs between the live run and the run on its dump"; exit 1
  fi
done
files=0
for f in "$work"/out_live/frames/* "$work"/out_live/*.pvd; do
  rel="${f#"$work"/out_live/}"
  cmp "$f" "$work/out_files/$rel" || { echo "$rel differs between the live run and the run on its dump"; exit 1; }
  files=$((files + 1))
done
# Per frame: the grid's .vti, the particles' .vtp, 3 weights files; and 2 .pvd files.
[ "$files" -eq $((5 * couplings + 2)) ] || { echo "$files files compared, expected $((5 * couplings + 2))"; exit 1; }
grep -q 'Name="Us_pmm_incremental"' "$work/out_live/frames/grid_$((250 * couplings)).vti" || { echo "no Us in the last frame"; exit 1; }

# A driver that fails (no such input) stops the run, naming the command.
scene broken "{command: \"'$driver' --input no_such_input --dump -\"}"
if "$cli" run "$work/broken.yaml" -q >/dev/null 2>"$work/broken.log"; then echo "a failing driver was not an error"; exit 1; fi
grep -q "vfe: error: command '.*vfe_liggghts' --input no_such_input --dump -' exited with status" "$work/broken.log" ||
  { cat "$work/broken.log"; echo "the error does not name the command"; exit 1; }
echo "live: $couplings frames from vfe_liggghts equal the run on the same frames as a dump ($files files, every report column)"
