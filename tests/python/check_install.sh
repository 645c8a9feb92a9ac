#!/usr/bin/env bash
# Installs a built tree into a temporary prefix and imports the installed vfe package from
# there, checking that it loads the installed libvfe.so and computes.
# Usage: check_install.sh BUILD_DIR PYTHON SITE_DIR (SITE_DIR relative to the prefix)
set -euo pipefail
build="$1" python="$2" site="$3"
prefix="$(mktemp -d)"
trap 'rm -rf "$prefix"' EXIT
cmake --install "$build" --prefix "$prefix" >/dev/null
test -f "$prefix/$site/vfe/__init__.py"
cd "$prefix"
PYTHONPATH="$prefix/$site" PYTHONDONTWRITEBYTECODE=1 "$python" - "$prefix" <<'PY'
import sys
import numpy as np
import vfe
prefix = sys.argv[1]
assert vfe.__file__.startswith(prefix), vfe.__file__
libs = [l.split()[-1] for l in open("/proc/self/maps") if "libvfe.so" in l]
assert libs and all(p.startswith(prefix) for p in libs), libs
e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(1, 1, 1), cells=(2, 2, 2))
e.configure(method="exact")
solid = e.compute(np.array([[1.0, 1.0, 1.0]]), np.array([0.5]))
assert abs(solid.sum() - 4 / 3 * np.pi / 8) < 1e-12
print("python install: vfe", vfe.__version__, "imports from", vfe.__file__)
PY
