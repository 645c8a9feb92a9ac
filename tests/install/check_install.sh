#!/usr/bin/env bash
# Installs a built tree into a temporary prefix and builds host programs against it three
# ways: plain cc, pkg-config and CMake's find_package. Usage: check_install.sh BUILD_DIR
set -euo pipefail
build="$1"
here="$(cd "$(dirname "$0")" && pwd)"
prefix="$(mktemp -d)"
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix" >/dev/null
libdir="$prefix/lib"
[ -d "$libdir" ] || libdir="$(dirname "$(find "$prefix" -name 'libvfe.so' | head -1)")"
test -f "$prefix/include/vfe/vfe.h"
test -f "$libdir/libvfe.so"
cc -std=c99 -Wall -pedantic "$here/host.c" -I "$prefix/include" -L "$libdir" -lvfe -o "$prefix/host_cc"
LD_LIBRARY_PATH="$libdir" "$prefix/host_cc"
PKG_CONFIG_PATH="$libdir/pkgconfig" cc -std=c99 "$here/host.c" $(PKG_CONFIG_PATH="$libdir/pkgconfig" pkg-config --cflags --libs vfe) -o "$prefix/host_pc"
LD_LIBRARY_PATH="$libdir" "$prefix/host_pc"
cmake -S "$here" -B "$prefix/host_build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$prefix/host_build" >/dev/null
"$prefix/host_build/host"
echo "install: header, libvfe.so, pkg-config and CMake package work"
