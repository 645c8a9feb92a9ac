#!/usr/bin/env bash
# Fetches a Debian source package (apt-get source: unpacked, Debian's patches applied) into
# DIR, from deb-src entries made from the machine's own apt sources (deb822 and one-line
# formats), in a private apt state under DIR/apt so the system's sources and lists are left
# as they are. Needs dpkg-dev and network access to the machine's Debian mirrors.
# Usage: scripts/apt_source.sh DIR PACKAGE=VERSION
set -euo pipefail
dir="$1" spec="$2"
apt="$dir/apt"
mkdir -p "$apt/sources.list.d" "$apt/lists/partial" "$apt/cache/archives/partial"
shopt -s nullglob
for f in /etc/apt/sources.list.d/*.sources; do
  sed -E 's/^Types:.*/Types: deb-src/' "$f" >"$apt/sources.list.d/$(basename "$f")"
done
for f in /etc/apt/sources.list /etc/apt/sources.list.d/*.list; do
  [ -f "$f" ] && sed -nE 's/^deb[[:space:]]+(.*)/deb-src \1/p' "$f" >>"$apt/sources.list.d/deb-src.list"
done
apt_private=(-o "Dir::Etc::SourceList=/dev/null" -o "Dir::Etc::SourceParts=$apt/sources.list.d"
             -o "Dir::State::Lists=$apt/lists" -o "Dir::Cache=$apt/cache")
apt-get "${apt_private[@]}" update -qq
(cd "$dir" && apt-get "${apt_private[@]}" source -qq "$spec")
