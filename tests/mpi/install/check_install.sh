#!/usr/bin/env bash
# Installs a built tree into a temporary prefix and builds a C host of libvfe_mpi against it
# with mpicc, pkg-config and CMake's find_package, each run on 2 ranks, with no
# LD_LIBRARY_PATH (the library's RPATH and pkg-config's find libvfe).
# Usage: check_install.sh BUILD_DIR MPIEXEC [MPIEXEC_FLAGS...]
set -euo pipefail
build="$1"
shift
run=("$1" -np 2 "${@:2}")
here="$(cd "$(dirname "$0")" && pwd)"
prefix="$(mktemp -d)"
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix" >/dev/null
libdir="$(dirname "$(find "$prefix" -name 'libvfe_mpi.so' | head -1)")"
test -f "$prefix/include/vfe/vfe_mpi.h"
unset LD_LIBRARY_PATH
mpicc -std=c99 -Wall -pedantic "$here/host_mpi.c" -I "$prefix/include" -L "$libdir" -Wl,-rpath,"$libdir" -lvfe_mpi -lvfe -lm \
  -o "$prefix/host_cc"
"${run[@]}" "$prefix/host_cc"
export PKG_CONFIG_PATH="$libdir/pkgconfig"
cc -std=c99 "$here/host_mpi.c" $(pkg-config --cflags --libs vfe_mpi) -lm -o "$prefix/host_pc"
"${run[@]}" "$prefix/host_pc"
cmake -S "$here" -B "$prefix/host_build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$prefix/host_build" >/dev/null
"${run[@]}" "$prefix/host_build/host_mpi"
echo "install: vfe_mpi.h, libvfe_mpi.so, pkg-config vfe_mpi and CMake vfe::vfe_mpi work"
