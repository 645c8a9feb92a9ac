#!/usr/bin/python3
"""Cost of a compute called from Python against the same compute called through the C API
directly (ctypes, no module in between), in one process, on the same arrays and engine
options: direct and pmm on the settled bed's 10 x 10 x 30 grid, for 1, 100 and 20000 spheres.

    PYTHONPATH=build/release/python /usr/bin/python3 examples/python_overhead.py build/release/engine/libvfe.so

Per case: the fastest of 9 rounds of the mean time per call of a batch of calls, the two
ways taking turns in every round (one thread). The C API column includes ctypes' own call cost.
"""
import ctypes
import pathlib
import sys
import time

import numpy as np

import vfe

ROOT = pathlib.Path(__file__).resolve().parents[1]


def per_call(fns, calls, rounds=9):
    """Seconds per call of each function in its fastest round (the least disturbed by other
    load); the functions take turns within every round so a busy machine slows them alike."""
    times = [[] for _ in fns]
    for fn in fns:  # warm-up: templates, rotation bank, caches
        for _ in range(calls):
            fn()
    for _ in range(rounds):
        for fn, t in zip(fns, times):
            t0 = time.perf_counter()
            for _ in range(calls):
                fn()
            t.append((time.perf_counter() - t0) / calls)
    return [min(t) for t in times]


def main():
    lib = ctypes.CDLL(sys.argv[1] if len(sys.argv) > 1 else "libvfe.so")
    d3, i3, dp = ctypes.c_double * 3, ctypes.c_int64 * 3, ctypes.POINTER(ctypes.c_double)
    lib.vfe_create_cartesian.argtypes = [d3, d3, i3, ctypes.POINTER(ctypes.c_void_p)]
    lib.vfe_configure.argtypes = [ctypes.c_void_p, ctypes.c_char_p]
    lib.vfe_compute.argtypes = [ctypes.c_void_p, ctypes.c_int64, dp, dp, dp, dp]
    lib.vfe_destroy.argtypes = [ctypes.c_void_p]

    frame = vfe.read_dump(ROOT / "data" / "liggghts" / "bed_mono_final.dump.gz")
    centres_all, radii_all = vfe.particles(frame)
    print("| method | particles | Python us/call | C API us/call | Python - C API, us | ratio |")
    print("|---|---:|---:|---:|---:|---:|")
    for method in ("direct", "pmm"):
        for n in (1, 100, 20000):
            centres = np.ascontiguousarray(centres_all[:n])
            radii = np.ascontiguousarray(radii_all[:n])
            options = f"method={method} threads=1"
            e = vfe.Engine.cartesian(origin=(0, 0, 0), spacing=(0.002,) * 3, cells=(10, 10, 30))
            e.configure(options)
            out = np.zeros(e.cell_count)
            handle = ctypes.c_void_p()
            lib.vfe_create_cartesian(d3(0, 0, 0), d3(0.002, 0.002, 0.002), i3(10, 10, 30), ctypes.byref(handle))
            lib.vfe_configure(handle, options.encode())
            c_out = np.zeros(e.cell_count)
            args = (handle, n, centres.ctypes.data_as(dp), radii.ctypes.data_as(dp), None, c_out.ctypes.data_as(dp))
            calls = max(3, 20000 // n)
            t_py, t_c = per_call([lambda: e.compute(centres, radii, out=out), lambda: lib.vfe_compute(*args)], calls)
            assert np.array_equal(out, c_out)
            lib.vfe_destroy(handle)
            print(f"| {method} | {n} | {1e6 * t_py:.2f} | {1e6 * t_c:.2f} | {1e6 * (t_py - t_c):.2f} | "
                  f"{t_py / t_c:.3f} |")


if __name__ == "__main__":
    main()
