#!/usr/bin/env bash
# Installs a built tree into a temporary prefix and proves it usable as the README says,
# with no LD_LIBRARY_PATH anywhere: bin/vfe runs; a C host built with the README's cc line,
# one built with pkg-config's flags, and C and C++ hosts built through find_package(vfe
# CONFIG) and vfe::vfe run and load the installed libvfe; libvfe exports its public API only.
# Usage: check_install.sh BUILD_DIR
set -euo pipefail
build="$1"
here="$(cd "$(dirname "$0")" && pwd)"
source_dir="$(cd "$here/../.." && pwd)"
prefix="$(mktemp -d)"
trap 'rm -rf "$prefix"' EXIT
unset LD_LIBRARY_PATH
fail() { echo "install: $*" >&2; exit 1; }

cmake --install "$build" --prefix "$prefix" >/dev/null
libdir="$prefix/lib"
[ -d "$libdir" ] || libdir="$(dirname "$(find "$prefix" -name 'libvfe.so' | head -1)")"
for f in include/vfe/vfe.h include/vfe/version.h include/vfe/engine.hpp bin/vfe; do
  [ -f "$prefix/$f" ] || fail "$f is not installed"
done
[ -f "$libdir/libvfe.so" ] || fail "libvfe.so is not installed"

# Runs a program and checks that it loaded libvfe from the prefix, not from the build tree.
run_installed() {
  local program="$1"; shift
  local loaded
  loaded="$(ldd "$program" | awk '/libvfe\.so/ {print $3}')"
  [ -n "$loaded" ] && [ "$(readlink -f "$loaded")" = "$(readlink -f "$libdir/libvfe.so")" ] ||
    fail "$(basename "$program") does not load $libdir/libvfe.so: $(ldd "$program" | grep libvfe)"
  "$program" "$@"
}

# bin/vfe finds libvfe through its install RPATH ($ORIGIN/../lib).
run_installed "$prefix/bin/vfe" --help >/dev/null
echo "install: bin/vfe --help runs"

# The README's cc line, as written there, with P the prefix.
readme_cc="$(grep -o 'cc -std=c99 host.c [^`]*' "$source_dir/README.md" | head -1)"
[ -n "$readme_cc" ] || fail "no 'cc -std=c99 host.c ...' line in README.md"
(cd "$here" && eval "${readme_cc//P\//$prefix/} -Wall -pedantic -o '$prefix/host_cc'")
run_installed "$prefix/host_cc"
echo "install: the README's line ($readme_cc) builds a host that runs"

export PKG_CONFIG_PATH="$libdir/pkgconfig"
pkg-config --exists vfe || fail "pkg-config does not find vfe in $PKG_CONFIG_PATH"
[ "$(pkg-config --modversion vfe)" = "$("$prefix/bin/vfe" --version | awk '{print $NF}')" ] ||
  fail "pkg-config's version $(pkg-config --modversion vfe) is not the library's"
# shellcheck disable=SC2046  # the flags are separate words
cc -std=c99 "$here/host.c" $(pkg-config --cflags --libs vfe) -o "$prefix/host_pc"
run_installed "$prefix/host_pc"
echo "install: pkg-config's flags ($(pkg-config --cflags --libs vfe)) build a host that runs"

cmake -S "$here" -B "$prefix/host_build" -DCMAKE_PREFIX_PATH="$prefix" >/dev/null
cmake --build "$prefix/host_build" >/dev/null
run_installed "$prefix/host_build/host"
run_installed "$prefix/host_build/host_cpp"
echo "install: find_package(vfe CONFIG) hosts in C and C++ (vfe/engine.hpp) build and run"

# Hidden symbols: every vfe symbol libvfe.so exports is one its installed headers declare
# VFE_API (C functions, facade classes and functions); the standard-library templates it
# instantiates are exported too, as usual.
headers=("$prefix/include/vfe/"*.h "$prefix/include/vfe/"*.hpp "$prefix/include/vfe/detail/"*.hpp)
declared="$(cat "${headers[@]}" | tr '\n' ' ' | grep -oE 'VFE_API [^;{]*' |
  sed -E 's/^VFE_API +//; /\(/{s/ *\(.*//; s/.*[ *&]//; b}; s/[ :].*//')"
exported="$(nm -D --defined-only "$libdir/libvfe.so" | awk '{print $3}' | grep -E '^vfe_' || true)
$(nm -D --defined-only -C "$libdir/libvfe.so" | cut -d' ' -f3- |
  sed -nE 's/^((typeinfo|typeinfo name|vtable) for )?vfe::(detail::)?([A-Za-z_0-9]+).*/\4/p')"
for name in $(sort -u <<<"$exported"); do
  grep -qx "$name" <<<"$declared" || fail "libvfe.so exports $name, which no installed header declares VFE_API"
done
echo "install: libvfe.so exports $(sort -u <<<"$exported" | grep -c .) names, all declared VFE_API in the installed headers"
