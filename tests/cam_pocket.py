"""A CAM-style 2D pocket as Fusion's and FreeCAD's pocket operations post it, written without millpost:
offset rings from the inside out at several depths, the outer ring's R_c tool-centre corner arcs slowed
by the CAM's own rule (feed × R_path / R_wall, so the edge runs at the straights' feed), a plunge
from the feed height (within the air clearance) at each level, level changes through the pocket already
cut (retract to 1 mm over the last floor, move over, down to it, plunge), and a finishing ring.

`write_job(folder, ...)` writes program.nc and job.toml and returns the job folder; `pocket_program`
returns the text alone."""

from __future__ import annotations

from pathlib import Path


def _ring(x0: float, y0: float, x1: float, y1: float, r: float, feed: float, corner_feed: float) -> list[str]:
    """A climb ring (CCW inside a pocket) of the tool centre around [x0, x1] × [y0, y1] from (x1, y0 + r)
    with corner arcs of radius r (none where r = 0), corners at corner_feed."""
    out = [f"G1 X{x1:.4f} Y{y0 + r:.4f} F{feed:g}"]
    corners = [((x1, y1 - r), (x1 - r, y1), (-r, 0)), ((x0 + r, y1), (x0, y1 - r), (0, -r)),
               ((x0, y0 + r), (x0 + r, y0), (r, 0)), ((x1 - r, y0), (x1, y0 + r), (0, r))]
    for (sx, sy), (ex, ey), (i, j) in corners:
        out.append(f"G1 X{sx:.4f} Y{sy:.4f} F{feed:g}")
        if r > 0:
            out.append(f"G3 X{ex:.4f} Y{ey:.4f} I{i:.4f} J{j:.4f} F{corner_feed:g}")
    return out


def pocket_program(*, width: float = 40.0, height: float = 30.0, wall_radius: float = 4.0, tool_d: float = 6.0,
                   stepover: float = 2.4, step_down: float = 2.0, depth: float = 6.0, feed: float = 1000.0,
                   plunge_feed: float = 300.0, rpm: float = 9000.0, feed_height: float = 2.0,
                   origin: tuple[float, float] = (10.0, 10.0)) -> str:
    """The program (mm, G94) of a width × height pocket with wall_radius corners, its top at Z0."""
    R = tool_d / 2
    ox, oy = origin
    cx, cy = ox + width / 2, oy + height / 2
    lines = ["%", "(CAM-STYLE POCKET)", "G90 G94 G17 G21", "T1 M6", f"S{rpm:g} M3", "G0 Z15",
             f"G0 X{cx:.4f} Y{cy:.4f}", "G0 Z5"]
    levels = [-min(step_down * (k + 1), depth) for k in range(int(-(-depth // step_down)))]
    last_floor = 0.0
    for n, z in enumerate(levels):
        if n == 0:
            lines += [f"G1 Z{feed_height:g} F{plunge_feed:g}", f"G1 Z{z:g} F{plunge_feed:g}"]
        else:  # a level change through the pocket already cut: 1 mm over its floor, across, down
            lines += [f"G1 Z{last_floor + 1:g} F{feed:g}", f"G1 X{cx:.4f} Y{cy:.4f} F{feed:g}",
                      f"G1 Z{last_floor:g} F{plunge_feed:g}", f"G1 Z{z:g}"]
        inset = R
        rings = []
        while True:
            half_w, half_h = width / 2 - inset, height / 2 - inset
            if half_w <= 0 or half_h <= 0:
                break
            rings.append((inset, half_w, half_h))
            inset += stepover
        for inset, half_w, half_h in reversed(rings):  # from the inside out
            r = max(wall_radius - inset, 0.0)
            r_wall = r + R
            corner = round(feed * r / r_wall, 1) if r > 0 else feed
            lines.append(f"G1 X{cx:.4f} Y{cy:.4f} F{feed:g}")
            lines += _ring(cx - half_w, cy - half_h, cx + half_w, cy + half_h, r, feed, corner)
        last_floor = z
    lines += ["G0 Z15", "M5", "M30", "%"]
    return "\n".join(lines) + "\n"


def write_job(folder: Path, *, material: str = "al6061", machine: str = "vmc-small", **kw) -> Path:
    """program.nc and job.toml of the pocket in `folder` (stock: a block 10 mm larger all round)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "program.nc").write_text(pocket_program(**kw))
    ox, oy = kw.get("origin", (10.0, 10.0))
    w, h = kw.get("width", 40.0), kw.get("height", 30.0)
    (folder / "job.toml").write_text(
        f'program = "program.nc"\nmaterial = "{material}"\nmachine = "{machine}"\n'
        f"[stock]\nbox = [[{ox - 10}, {oy - 10}, -20], [{ox + w + 10}, {oy + h + 10}, 0]]\ncell_mm = 0.05\n"
        f"[tools.1]\ndiameter_mm = {kw.get('tool_d', 6.0)}\nflutes = 3\nshape = \"flat\"\nhelix_deg = 35\n"
        "flute_length_mm = 16\nstickout_mm = 24\n")
    return folder
