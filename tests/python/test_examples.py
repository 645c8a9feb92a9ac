"""The examples run: the LAMMPS pour (when Debian's LAMMPS is installed) conserves volume
and reads LAMMPS's arrays without a copy."""
import os
import subprocess
import sys

import pytest

from conftest import SOURCE_DIR


def test_lammps_pour_conserves_volume_without_copies():
    pytest.importorskip("lammps", reason="python3-lammps and liblammps-dev are not installed")
    try:
        from lammps import lammps
        lammps(cmdargs=["-log", "none", "-screen", "none"]).close()
    except OSError as e:
        pytest.skip(f"LAMMPS cannot be loaded ({e}); install liblammps-dev")
    run = subprocess.run([sys.executable, str(SOURCE_DIR / "examples" / "lammps_pour.py"), "--particles", "300",
                          "--steps", "2000", "--every", "1000"], capture_output=True, text=True, env=os.environ,
                         timeout=120, check=True)
    rows = [line.split("|")[1:-1] for line in run.stdout.splitlines() if line.startswith("| 1000") or
            line.startswith("| 2000")]
    assert len(rows) == 2
    for step, particles, conservation, _, _, _, copies in rows:
        assert int(particles) > 0
        assert abs(float(conservation) - 1) < 1e-9 and int(copies) == 0
