#!/usr/bin/env bash
# Installs vfe's dependencies from Debian 12 packages when missing, then configures and
# builds one CMake preset (default: release). Usage: scripts/setup.sh [release|audit|tsan|profiling|openfoam]
# tsan first builds oneTBB with ThreadSanitizer (scripts/tbb_tsan.sh). Compiles go through
# ccache (cache in HOME), so repeated builds of a preset are cheap.
# openfoam also installs OpenFOAM and LIGGGHTS and builds the hosts: release, then
# build/openfoam/lib/libvfeFunctionObject.so (hosts/openfoam/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
preset="${1:-release}"
hosts=""
[ "$preset" = openfoam ] && { hosts=openfoam; preset=release; }

packages=(g++ cmake ninja-build pkg-config libtbb-dev libeigen3-dev libnanoflann-dev libspdlog-dev
          libyaml-cpp-dev libcli11-dev zlib1g-dev libgtest-dev libbenchmark-dev python3-matplotlib ccache
          pybind11-dev python3-pybind11 python3-numpy python3-pytest
          libopenmpi-dev openmpi-bin)  # MPI: libvfe_mpi and its tests
if [ "$preset" = tsan ]; then packages+=(dpkg-dev xz-utils); fi
# LAMMPS for examples/lammps_pour.py, where the distribution has it (liblammps-dev gives the
# liblammps.so that the Python module loads).
for p in python3-lammps liblammps-dev; do
  apt-cache show "$p" >/dev/null 2>&1 && packages+=("$p")
done
# The hosts: Debian's OpenFOAM (libraries and tools; its headers and wmake come from the
# source package, dpkg-dev fetches it), LIGGGHTS's library and MPI.
[ -n "$hosts" ] && packages+=(openfoam libopenfoam dpkg-dev libliggghts-dev libopenmpi-dev openmpi-bin)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing ${missing[*]}"
  sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "setup: run as root or install sudo to install: ${missing[*]}" >&2; exit 1; }
    sudo="sudo"
  fi
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

if [ "$preset" = tsan ]; then scripts/tbb_tsan.sh; fi
cmake --preset "$preset" >/dev/null
cmake --build --preset "$preset" -j "$(nproc)"
if [ -n "$hosts" ]; then
  hosts/openfoam/build.sh "build/$preset"
  cmake --preset "$preset" >/dev/null    # registers the function object's test now that it exists
fi
