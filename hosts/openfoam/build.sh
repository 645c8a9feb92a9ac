#!/usr/bin/env bash
# Builds the OpenFOAM function object build/openfoam/lib/libvfeFunctionObject.so against
# Debian's OpenFOAM (packages openfoam, libopenfoam: libraries, no headers, no wmake).
# Headers and wmake come from the Debian source package of the same version, fetched once
# into build/openfoam/src (scripts/apt_source.sh) and reused (about 300 MB). vfe is
# installed from BUILD_DIR into build/openfoam (include/, lib/), where the function object
# finds it; so is libvfe_mpi, which it uses on a decomposed case (-parallel).
# Usage: hosts/openfoam/build.sh [BUILD_DIR (default build/release)]
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
build_dir="${1:-$root/build/release}"
out="$root/build/openfoam"
mkdir -p "$out/src"
step() { echo "openfoam: $1 ($(( $(date +%s) - t0 )) s)"; }

t0=$(date +%s)
foam_src="$(find "$out/src" -maxdepth 1 -type d -name 'openfoam-*' | head -1)"
if [ -z "$foam_src" ]; then
  "$root/scripts/apt_source.sh" "$out/src" "$(dpkg-query -W -f='${source:Package}=${source:Version}' openfoam)" >/dev/null
  foam_src="$(find "$out/src" -maxdepth 1 -type d -name 'openfoam-*' | head -1)"
  step "fetched the OpenFOAM source package"
fi

# The source tree's environment for wmake; it compiles against the packaged libraries in
# /usr/lib (same version), not against a build of its own.
set +u
# shellcheck disable=SC1091
. "$foam_src/etc/bashrc" WM_PROJECT_DIR="$foam_src" >/dev/null 2>&1 || true
set -u
if [ ! -e "$foam_src/.vfe_wmake_done" ]; then
  "$foam_src/wmake/src/Allmake" >/dev/null 2>&1
  for d in OpenFOAM OSspecific/POSIX finiteVolume meshTools; do wmakeLnInclude -u "$foam_src/src/$d" >/dev/null 2>&1; done
  touch "$foam_src/.vfe_wmake_done"
  step "built wmake and the lnInclude folders"
fi

# The install rules of the engine and of libvfe_mpi only (headers, libraries, CMake and
# pkg-config files).
test -f "$build_dir/mpi/cmake_install.cmake" ||
  { echo "openfoam: $build_dir has no libvfe_mpi (configure it where MPI is found: libopenmpi-dev)" >&2; exit 1; }
cmake --install "$build_dir/engine" --prefix "$out" >/dev/null
cmake --install "$build_dir/mpi" --prefix "$out" >/dev/null
step "installed vfe and vfe_mpi into build/openfoam"

# wmake writes its objects next to the sources: build from a copy under build/.
rm -rf "$out/obj" && mkdir -p "$out/obj" && cp -r "$root/hosts/openfoam/Make" "$root"/hosts/openfoam/*.[CH] "$out/obj/"
# The MPI that libvfe_mpi was built with (its pkg-config file requires mpi-c).
VFE_MPI_CFLAGS="$(pkg-config --cflags mpi-c)" VFE_MPI_LIBS="$(pkg-config --libs mpi-c)"
export VFE_PREFIX="$out" FOAM_USER_LIBBIN="$out/lib" VFE_MPI_CFLAGS VFE_MPI_LIBS
(cd "$out/obj" && wmake -s libso >/dev/null)
test -f "$out/lib/libvfeFunctionObject.so"
step "built build/openfoam/lib/libvfeFunctionObject.so"
