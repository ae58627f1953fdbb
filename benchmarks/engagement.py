"""Engagement benchmark: 100×100×50 mm block at 25 µm, D6 flat and ball end mills, ap 2 mm, 0.1 mm
steps, on a slot pattern, a zig-zag pocket (ae = 0.4D) and a trochoid; plus rasterising a mesh
with an undercut into the stock. Prints one JSON object: steps/s, the process's peak RSS, and the
peak RSS of each phase (engagement; mesh to stock), which includes what the process held when the
phase began (interpreter, numpy, compiled kernels: `loaded_rss_mb`, the RSS once they are loaded and
before the first stock). The test part's triangles are made in a child
process, as a file would be read: manifold3d's booleans leave ~15 MB of freed heap with the allocator
that is the benchmark's input, not the stock's. CPU seconds of the whole run as `cpu_s`;
`steps_per_cpu_s` counts this thread's CPU time only (on a shared machine the wall-clock rate also
measures the other processes).

`ratio_vs_numpy` compares with a straightforward per-step numpy version of the same algorithm
(full-disk window update, ring of 181 immersion samples per slice, no bisection), timed in the same
run on the first steps of each path. One core; the numba kernels are compiled (and cached) first.

Run: PYTHONPATH=src python benchmarks/engagement.py [--cell 0.025]
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
import resource
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from millpost import stock as stk
from millpost.engagement import simulate
from millpost.toolpath import FEED, Toolpath
from millpost.tools import Tool

TOP, Z = 50.0, 48.0
ROT = math.radians(7)  # paths turned off the grid
CENTRE = np.array([50.0, 50.0])


def polyline(xy: np.ndarray, z: float = Z) -> Toolpath:
    c, s = math.cos(ROT), math.sin(ROT)
    q = (xy - CENTRE) @ np.array([[c, s], [-s, c]]) + CENTRE + 0.0123
    pts = np.column_stack([q, np.full(len(q), z)])
    n = len(pts) - 1
    return Toolpath(kind=np.full(n, FEED, np.int8), start=pts[:-1], end=pts[1:], center=np.full((n, 3), np.nan),
                    plane=np.zeros(n, np.int8), turns=np.zeros(n, np.int32), feed_mm_min=np.full(n, 1000.0),
                    rpm=np.full(n, 12000.0), tool=np.ones(n, np.int32), line=np.arange(1, n + 1, dtype=np.int32),
                    block=np.arange(n, dtype=np.int32))


def slot_path() -> Toolpath:
    """10 full slots across the block, linked outside it."""
    pts = []
    for i, y in enumerate(np.linspace(12, 88, 10)):
        xs = (-5.0, 105.0) if i % 2 == 0 else (105.0, -5.0)
        pts += [(xs[0], y), (xs[1], y)]
    return polyline(np.array(pts))


def zigzag_path() -> Toolpath:
    """10 passes 80 mm long, 0.4D apart, inside the block (the first is a slot)."""
    pts = []
    for i in range(10):
        y = 30 + i * 2.4
        xs = (10.0, 90.0) if i % 2 == 0 else (90.0, 10.0)
        pts += [(xs[0], y), (xs[1], y)]
    return polyline(np.array(pts))


def trochoid_path() -> Toolpath:
    """200 loops of radius 1.5 mm advancing 0.3 mm per loop, as a 0.1 mm polyline."""
    loops, rt, adv = 200, 1.5, 0.3
    t = np.linspace(0, loops * 2 * math.pi, int(loops * 2 * math.pi * rt / 0.1) + 1)
    return polyline(np.column_stack([20 + adv * t / (2 * math.pi) + rt * np.sin(t), 50 - rt * np.cos(t)]))


def numpy_steps(stock: stk.Stock, tool: Tool, xyz: np.ndarray, K: int = 8, M: int = 180, L: float = 0.27) -> None:
    """Straightforward numpy engine: per step, cut the full disk window, then sample the ring."""
    top, h, x0, y0, zf, R = stock.top, stock.cell_mm, stock.x0, stock.y0, stock.z_floor, tool.radius_mm
    xyz = xyz - np.array([0.0, 0.0, stock.z0])  # in the stock's heights (above its z0), as top and zf are
    phi = np.linspace(0, math.pi, M + 1)
    bilinear = tool.shape != "flat"
    for k in range(1, len(xyz)):
        (px, py, pz), d = xyz[k], xyz[k] - xyz[k - 1]
        dxy = math.hypot(d[0], d[1])
        if dxy == 0:
            continue
        f = d[:2] / dxy
        i0, i1 = max(0, int((px - R - x0) / h)), min(stock.nx, int((px + R - x0) / h) + 2)
        j0, j1 = max(0, int((py - R - y0) / h)), min(stock.ny, int((py + R - y0) / h) + 2)
        xs = x0 + (np.arange(i0, i1) + 0.5) * h - px
        ys = y0 + (np.arange(j0, j1) + 0.5) * h - py
        r = np.hypot(xs[None, :], ys[:, None])
        zc = np.maximum(pz + tool.height_at(np.minimum(r, R)), zf)
        win = top[j0:j1, i0:i1]
        new = np.where(r <= R, np.minimum(win, zc), win)
        cut = win > new
        ap = float((win - pz)[cut].max()) if cut.any() else 0.0
        top[j0:j1, i0:i1] = new
        if ap <= 1e-6:
            continue
        c = np.array([px, py]) + L * f
        n = np.array([-f[1], f[0]])
        dz = ap / K
        area = 0.0
        for s in range(K):
            rk = float(tool.radius_at((s + 0.5) * dz))
            q = c + rk * (np.sin(phi)[:, None] * f + np.cos(phi)[:, None] * n)
            if bilinear:
                u, v = (q[:, 0] - x0) / h - 0.5, (q[:, 1] - y0) / h - 0.5
                iu, iv = np.floor(u).astype(int), np.floor(v).astype(int)
                wu, wv = u - iu, v - iv
                iu, iv = np.clip(iu, 0, stock.nx - 2), np.clip(iv, 0, stock.ny - 2)
                H = ((1 - wv) * ((1 - wu) * top[iv, iu] + wu * top[iv, iu + 1])
                     + wv * ((1 - wu) * top[iv + 1, iu] + wu * top[iv + 1, iu + 1]))
            else:
                H = top[np.clip(((q[:, 1] - y0) / h).astype(int), 0, stock.ny - 1),
                        np.clip(((q[:, 0] - x0) / h).astype(int), 0, stock.nx - 1)]
            m = np.clip(np.minimum(H, pz + (s + 1) * dz) - np.maximum(zf, pz + s * dz), 0, None)
            on = m > 0.5 * dz
            area += np.trapezoid(rk * np.sin(phi) * m, phi)
            if on.any():
                _ = phi[on][0], phi[on][-1]


def mesh_part():
    """100×100×50 block less a pocket and a Ø12 horizontal through hole (an undercut), plus a dome."""
    import manifold3d as m3

    M = m3.Manifold
    blk = M.cube((100, 100, 50))
    pocket = M.cube((40, 30, 15)).translate((10, 10, 35))
    hole = M.cylinder(120, 6, 6, 256).rotate((0, 90, 0)).translate((-10, 70, 20))
    dome = M.sphere(10, 256).translate((70, 30, 50))
    part = (blk - pocket - hole) + dome
    mesh = part.to_mesh()
    v, t = np.asarray(mesh.vert_properties)[:, :3], np.asarray(mesh.tri_verts)
    return v[t].astype(np.float64), part.volume()


def reset_peak() -> None:
    """Start a new peak-RSS phase (Linux: clear_refs 5 resets VmHWM; elsewhere the run's peak stays)."""
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def status_mb(field: str) -> float | None:
    """A memory field of /proc/self/status (MB), or None where /proc is missing."""
    try:
        with open("/proc/self/status") as f:
            return next(round(int(ln.split()[1]) / 1024, 1) for ln in f if ln.startswith(field + ":"))
    except (OSError, StopIteration):
        return None


def peak_mb() -> float | None:
    """Peak RSS since the last `reset_peak` (MB; VmHWM)."""
    return status_mb("VmHWM")


def peak_rss_mb(*phases: float | None) -> float:
    """The run's peak RSS (MB): the highest peak of the intervals between `reset_peak` calls (each also
    resets ru_maxrss), or ru_maxrss where they are not measured."""
    if all(p is not None for p in phases):
        return max(phases)
    return round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)


def engagement_phase(tools: dict[str, Tool], cell: float, numpy_n: int) -> tuple[dict, dict, dict, dict]:
    """Each tool along each path through a fresh block: (steps/s, steps/CPU s, ratio to numpy, steps)
    per "tool_path" key. Its paths and samples go when it returns (the mesh phase does not hold them)."""
    paths = {"slot": slot_path(), "zigzag": zigzag_path(), "trochoid": trochoid_path()}
    rates, cpu_rates, ratio, steps = {}, {}, {}, {}
    for tname, tool in tools.items():
        for pname, tp in paths.items():
            key = f"{tname}_{pname}"
            sm = tp.resample(0.1)
            stock = stk.box((0, 0, 0), (100, 100, TOP), cell)  # a fresh block (no second copy kept)
            t0, c0 = time.perf_counter(), time.thread_time()
            simulate(stock, tool, sm, progress=False)
            dt, dc = time.perf_counter() - t0, time.thread_time() - c0
            rates[key] = len(sm) / dt
            cpu_rates[key] = len(sm) / dc
            steps[key] = len(sm)
            del stock  # before the next block: one 64 MB stock at a time
            stock = stk.box((0, 0, 0), (100, 100, TOP), cell)
            n = min(numpy_n, len(sm))
            t0 = time.perf_counter()
            numpy_steps(stock, tool, sm.xyz_mm[:n])
            ratio[key] = rates[key] / (n / (time.perf_counter() - t0))
            del stock
    return rates, cpu_rates, ratio, steps


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cell", type=float, default=0.025)
    ap.add_argument("--numpy-steps", type=int, default=1500)
    args = ap.parse_args()
    tools = {"flat": Tool(6.0, flutes=3), "ball": Tool(6.0, flutes=3, shape="ball")}
    # compile (or load the cached compilation) on a small case first
    for t in tools.values():
        simulate(stk.box((0, 0, 0), (10, 10, 5), 0.1), t, polyline(np.array([(45, 50), (55, 50)]), 4.0).resample(0.1),
                 progress=False)
    # the OS's first grant of a block's memory (2 MB pages, compacted on a busy machine: ~0.1 s) falls outside
    # the timing, as it did when `stk.box` wrote the whole top; the stock's pages are committed as it is cut
    stk.box((0, 0, 0), (100, 100, TOP), args.cell).top[:] = 0.0
    loaded, warm_peak = status_mb("VmRSS"), peak_mb()
    reset_peak()
    rates, cpu_rates, ratio, steps = engagement_phase(tools, args.cell, args.numpy_steps)
    engagement_peak = peak_mb()
    with ProcessPoolExecutor(1, mp_context=multiprocessing.get_context("spawn")) as pool:
        tris, vol = pool.submit(mesh_part).result()
    between_peak = peak_mb()  # the engagement phase's and the child's start
    reset_peak()
    t0 = time.perf_counter()
    part = stk.from_triangles(tris, args.cell)
    mesh_s = time.perf_counter() - t0
    mesh_peak = peak_mb()
    print(json.dumps({
        "cell_mm": args.cell,
        "peak_rss_mb": peak_rss_mb(warm_peak, between_peak, mesh_peak),
        "loaded_rss_mb": loaded,
        "engagement_peak_rss_mb": engagement_peak,
        "mesh_to_stock_peak_rss_mb": mesh_peak,
        "cpu_s": round(time.process_time(), 1),
        "steps_per_s": {k: round(v) for k, v in rates.items()},
        "steps_per_cpu_s": {k: round(v) for k, v in cpu_rates.items()},
        "mesh_to_stock_s": round(mesh_s, 3),
        "ratio_vs_numpy": {k: round(v, 1) for k, v in ratio.items()},
        "steps": steps,
        "mesh": {"triangles": len(tris), "multi_columns": part.n_multi,
                 "volume_rel_error": (part.volume_mm3() - vol) / vol},
    }, indent=1))


if __name__ == "__main__":
    main()
