#!/usr/bin/env bash
# Builds oneTBB with ThreadSanitizer into build/tbb-tsan/prefix, from Debian's source package
# of the installed libtbb-dev (same version, same patches), once per version. TSan must see
# TBB's own synchronisation, or it reports false races between tasks. Needs dpkg-dev, network
# access to the machine's Debian mirrors, and about a minute on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
root="$PWD/build/tbb-tsan"
prefix="$root/prefix"
package="$(dpkg-query -W -f='${source:Package}' libtbb-dev)"
version="$(dpkg-query -W -f='${Version}' libtbb-dev)"
if [ "$(cat "$prefix/.debian-version" 2>/dev/null)" = "$package=$version" ]; then
  echo "tbb-tsan: $package $version with ThreadSanitizer is built"
  exit 0
fi
rm -rf "$root"
scripts/apt_source.sh "$root" "$package=$version"
source_dir="$(find "$root" -mindepth 1 -maxdepth 1 -type d -name "$package-*" | head -1)"
[ -n "$source_dir" ] || { echo "tbb-tsan: apt-get source $package=$version gave no source folder" >&2; exit 1; }

# Only libtbb itself: vfe uses neither tbbmalloc nor TBB's tests and examples.
cmake -S "$source_dir" -B "$root/build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_INSTALL_PREFIX="$prefix" \
  -DTBB_SANITIZE=thread -DTBB_TEST=OFF -DTBB_EXAMPLES=OFF -DTBB_STRICT=OFF -DTBBMALLOC_BUILD=OFF >/dev/null
if ! cmake --build "$root/build" -j "$(nproc)" >"$root/build.log" 2>&1; then
  tail -n 40 "$root/build.log" >&2
  exit 1
fi
cmake --install "$root/build" >/dev/null
echo "$package=$version" >"$prefix/.debian-version"
echo "tbb-tsan: built $package $version with ThreadSanitizer in $prefix"
