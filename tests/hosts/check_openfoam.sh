#!/usr/bin/env bash
# The function object in a real solver run: blockMesh of the packed-bed box, then
# scalarTransportFoam with vfeVoidFraction following the LIGGGHTS pour; its fields at
# t = 0.15 and 0.3 s must equal `vfe run --foam` on the dumps of those times (pmm without
# rotations, and exact), Us must carry the dump's momentum, and postProcess must rewrite
# the same fields. With NP > 1 also decomposePar + mpirun -np NP (libvfe_mpi's engine): the
# reconstructed fields must equal the serial ones, on this box and on a graded box whose
# cells differ across the processor boundary (pmm sizes a particle by its own cell).
# Usage: check_openfoam.sh SOURCE_DIR VFE_CLI [NP]
set -euo pipefail
src="$1"; cli="$2"; np="${3:-1}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
export WM_PROJECT_DIR=/usr/share/openfoam        # Debian's etc/bashrc does not set up a shell
export VFE_DATA="$src/data" LD_LIBRARY_PATH="$src/build/openfoam/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PYTHONPATH="${PYTHONPATH:-$src/build/release/python}"   # the vfe module reads the dumps
fields="$src/tests/hosts/foam_fields.py"
case="$work/case"
cp -r "$src/tests/hosts/openfoam_box" "$case"
(cd "$case" && blockMesh >log.blockMesh 2>&1 && scalarTransportFoam >log.solver 2>&1) ||
  { tail -n 30 "$case"/log.*; exit 1; }

for t in 0.15 0.3; do
  step=$(awk -v t="$t" 'BEGIN { printf "%d", t / 1e-5 + 0.5 }')
  cat >"$work/scene_$t.yaml" <<YAML
name: check_$t
particles: {file: $src/data/liggghts/bed_mono_frames/bed_mono_$step.dump.gz}
meshes: [{name: box, type: polymesh, path: $case}]
methods: [{method: pmm, options: "orientation=none", label: pmm_none}, exact]
reference: exact
repeats: 1
output: $work/run_$t
YAML
  "$cli" run "$work/scene_$t.yaml" --foam -q >/dev/null
  "$fields" diff "$case/$t/voidfraction" "$work/run_$t/box/0/voidfraction_pmm_none"
  "$fields" diff "$case/$t/voidfraction_exact" "$work/run_$t/box/0/voidfraction_exact"
  "$fields" momentum "$case" "$t" "$src/data/liggghts/bed_mono_frames/bed_mono_$step.dump.gz" --cell-volume 8e-9 --max 1e-9
done

# postProcess executes the controlDict's functions for the written times.
for t in 0.15 0.3; do mkdir -p "$case/solver_$t" && mv "$case/$t/voidfraction" "$case/$t/Us" "$case/solver_$t/"; done
(cd "$case" && postProcess >log.postProcess 2>&1) || { tail -n 30 "$case/log.postProcess"; exit 1; }
for t in 0.15 0.3; do
  "$fields" diff "$case/$t/voidfraction" "$case/solver_$t/voidfraction"
done

# A pattern that matches no dump stops the run with a message naming it.
sed -i 's|bed_mono_\*.dump.gz|no_such_*.dump.gz|' "$case/system/controlDict"
if (cd "$case" && postProcess -latestTime >log.badDumps 2>&1); then
  echo "postProcess ran with dumps that match nothing"; exit 1
fi
grep -q "no dump file matches '.*no_such_\*.dump.gz'" "$case/log.badDumps" ||
  { echo "no message naming the pattern:"; tail -n 20 "$case/log.badDumps"; exit 1; }
# A dump cut inside its atom list: the message names the file and line.
gzip -dc "$src/data/liggghts/bed_mono_frames/bed_mono_30000.dump.gz" | sed -n 1,5000p >"$work/cut_30000.dump"
sed -i "s|\"[^\"]*no_such_\*.dump.gz\"|\"$work/cut_*.dump\"|" "$case/system/controlDict"
if (cd "$case" && postProcess -latestTime >log.cutDump 2>&1); then
  echo "postProcess ran on a truncated dump"; exit 1
fi
grep -q "cut_30000.dump:5000: the file ends inside the atom list" "$case/log.cutDump" ||
  { echo "no message naming the truncated dump's line:"; tail -n 20 "$case/log.cutDump"; exit 1; }
sed -i "s|\"$work/cut_\*.dump\"|\"\$VFE_DATA/liggghts/bed_mono_frames/bed_mono_*.dump.gz\"|" "$case/system/controlDict"

if [ "$np" -gt 1 ]; then
  # Serial and parallel fields agree to round-off: ghost deposits are summed into their
  # owners in another order than a serial cell sums them (measured 1.6e-15, hosts/README.md).
  parallel_max=1e-14
  parallel() {  # CASE FIELD...: decomposePar, the case's application on NP ranks, reconstructPar
    local dir="$1" app; shift
    app=$(sed -n 's/^application *\([A-Za-z]*\);/\1/p' "$dir/system/controlDict")
    (cd "$dir" && decomposePar -force >log.decomposePar 2>&1 &&
       mpirun --allow-run-as-root --oversubscribe -np "$np" "$app" -parallel >log.parallel 2>&1 &&
       reconstructPar -fields "($*)" >log.reconstructPar 2>&1) ||
      { tail -n 30 "$dir"/log.*; exit 1; }
  }
  for t in 0.15 0.3; do
    mkdir -p "$case/serial_$t" && cp "$case/$t/voidfraction" "$case/$t/voidfraction_exact" "$case/$t/Us" "$case/serial_$t/"
  done
  parallel "$case" voidfraction voidfraction_exact Us
  for t in 0.15 0.3; do
    for f in voidfraction voidfraction_exact Us; do
      "$fields" diff "$case/$t/$f" "$case/serial_$t/$f" --max "$parallel_max"
    done
  done

  # The graded box at t = 0.3 s under postProcess: the decomposition cuts the bed between
  # layers of different cells, where a rank that computed every particle on its own cells
  # (sizing a particle centred on the other rank by its own nearest cell) differs by 7.7e-3.
  graded="$work/graded"
  cp -r "$src/tests/hosts/openfoam_graded" "$graded"
  mkdir -p "$graded/0.3" "$graded/serial"
  (cd "$graded" && blockMesh >log.blockMesh 2>&1 && postProcess >log.serial 2>&1) || { tail -n 30 "$graded"/log.*; exit 1; }
  cp "$graded/0.3/voidfraction" "$graded/0.3/voidfraction_divided" "$graded/serial/"
  parallel "$graded" voidfraction voidfraction_divided
  for f in voidfraction voidfraction_divided; do
    "$fields" diff "$graded/0.3/$f" "$graded/serial/$f" --max "$parallel_max"
  done
fi
echo "openfoam: the function object's fields equal vfe run's"
