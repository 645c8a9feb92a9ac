#!/usr/bin/env bash
# Regenerates data/openfoam/decomposed: the box and cylinder meshes split by decomposePar
# (method simple; Debian's scotch and metis are stubs) into 2, 3 and 4 processor folders,
# gzipped, for the libvfe_mpi polyMesh tests (tests/mpi/test_mpi_polymesh.cpp), which must
# not need OpenFOAM installed. Usage: scripts/decompose_test_meshes.sh (needs decomposePar).
set -euo pipefail
src="$(cd "$(dirname "$0")/.." && pwd)"
out="$src/data/openfoam/decomposed"
export WM_PROJECT_DIR="${WM_PROJECT_DIR:-/usr/share/openfoam}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
# mesh, subdomains, simple's n (x y z)
while read -r mesh np n; do
  case="$work/${mesh}_$np"
  cp -r "$src/data/openfoam/$mesh" "$case"
  cat >"$case/system/decomposeParDict" <<DICT
FoamFile { version 2.0; format ascii; class dictionary; object decomposeParDict; }
numberOfSubdomains $np;
method simple;
coeffs { n ($n); }
DICT
  (cd "$case" && decomposePar -force >log.decomposePar 2>&1) || { tail -n 20 "$case/log.decomposePar"; exit 1; }
  rm -rf "$out/${mesh}_$np"
  for ((p = 0; p < np; ++p)); do
    dest="$out/${mesh}_$np/processor$p/constant/polyMesh"
    mkdir -p "$dest"
    for f in points faces owner neighbour boundary pointProcAddressing faceProcAddressing cellProcAddressing; do
      gzip -9n <"$case/processor$p/constant/polyMesh/$f" >"$dest/$f.gz"
    done
  done
done <<LIST
box_uniform_10x10x30 2 1 1 2
box_uniform_10x10x30 3 1 1 3
box_uniform_10x10x30 4 2 2 1
cylinder_ogrid_coarse 2 2 1 1
cylinder_ogrid_coarse 3 1 1 3
cylinder_ogrid_coarse 4 2 1 2
LIST
echo "wrote $out"
