"""vfe: void fraction of CFD cells from DEM particles.

    import vfe, numpy as np
    e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(h, h, h), cells=(nx, ny, nz))
    e.configure("method=pmm", particle_grid="auto")
    solid = e.compute(centres, radii)      # (n, 3) and (n,) float64 -> (cell_count,) float64
    eps = e.void_fraction()
    r = e.report()

Engine, Error, stability_test and compare_fields come from the compiled engine (vfe._core);
read_dump and read_frames read LIGGGHTS/LAMMPS dumps; vfe.study times methods against exact.
"""
from ._core import (DEFAULT_JUMP_CRITERION, Engine, Error, compare_fields, method_names, stability_test,
                    status_name, version)
from .dump import DumpError, particles, read_dump, read_frames
from . import study

__version__ = version()
__all__ = ["Engine", "Error", "stability_test", "compare_fields", "method_names", "status_name", "version",
           "DEFAULT_JUMP_CRITERION", "read_dump", "read_frames", "particles", "DumpError", "study"]
