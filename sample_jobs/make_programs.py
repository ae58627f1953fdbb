"""Writes the sample jobs' programs (the project makes them itself, as a CAM system would post them).

    python sample_jobs/make_programs.py      # rewrites sample_jobs/*/program.nc

Each program is plain RS-274 as a Fusion/FreeCAD post writes it: G21 G90 G17, tool change, spindle,
rapids to a clearance height, one programmed feed per operation.
"""

from __future__ import annotations

import math
from pathlib import Path

HERE = Path(__file__).parent


def fmt(v: float) -> str:
    s = f"{v:.3f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def header(title: str, tool: int, rpm: int) -> list[str]:
    return [f"({title})", "G21 G90 G17 G94", f"T{tool} M6", f"S{rpm} M3", "G0 Z10"]


def adaptive_pocket() -> str:
    """Adaptive-style clearing of a 40 × 14 mm slot pocket, 6 mm deep, 6 mm 3-flute in Al 6061:
    trochoidal loops (radius 4 mm, 0.6 mm advance a loop) in fine linear segments, like Fusion's
    adaptive clearing posts them; one programmed feed for the whole operation."""
    out = header("adaptive pocket, 6 mm 3F flat, Al 6061", 1, 9000)
    r, step, y0, z = 4.0, 0.6, 7.0, -6.0
    x = -8.0  # start beside the stock and plunge in the air, as an adaptive entry from outside
    out += [f"G0 X{fmt(x + r)} Y{fmt(y0)}", "G0 Z2", f"G1 Z{fmt(z)} F400", "F1500"]
    while x + r <= 47.0:
        for k in range(1, 37):
            th = 2 * math.pi * k / 36
            px = x + r * math.cos(th) + step * k / 36
            py = y0 + r * math.sin(th)
            out.append(f"G1 X{fmt(px)} Y{fmt(py)}")
        x += step
    out += ["G0 Z10", "M30"]
    return "\n".join(out) + "\n"


def slotting() -> str:
    """Slotting-heavy job: three full-width slots 3 mm deep in two passes, then a side contour at
    ae = 1 mm around the block, 6 mm 3-flute in Al 6061, one feed per operation."""
    out = header("slots and contour, 6 mm 3F flat, Al 6061", 1, 9000)
    for y in (8.0, 20.0, 32.0):
        out += [f"G0 X-5 Y{fmt(y)}", "G0 Z2"]
        for z in (-1.5, -3.0):
            out += [f"G1 Z{fmt(z)} F300", "G1 X65 F700", "G0 Z2", f"G0 X-5 Y{fmt(y)}"]
    # the contour's centre line 2 mm outside the block (R − ae), entered 2 mm beside the -X face
    out += ["G0 Z10", "G0 X-5 Y-2", "G0 Z2", "G1 Z-4 F300", "G1 X62 F900", "Y42", "X-2", "Y-2", "G0 Z10", "M30"]
    return "\n".join(out) + "\n"


def ball_roughing() -> str:
    """First roughing level of a dome with a 6 mm ball end mill in POM: zig-zag rows 1.5 mm apart at
    z = max(dome + 0.3 mm stock, -1.5 mm), so the ball follows the dome where it rises above the level;
    one feed for the pass."""
    out = header("dome roughing level 1, 6 mm 2F ball, POM", 1, 16000)
    R, cx, cy, height = 20.0, 15.0, 15.0, 12.0

    def z_at(x: float, y: float) -> float:
        d2 = (x - cx) ** 2 + (y - cy) ** 2
        dome = -height + math.sqrt(max(R * R - d2, 0.0)) - (R - height) if d2 < R * R else -height
        return max(dome + 0.3, -1.5)

    out += ["G0 X-4 Y0", "G0 Z2", f"G1 Z{fmt(z_at(-4, 0))} F500", "F2500"]
    y, row = 0.0, 0
    while y <= 30.0:
        xs = [-4 + i * 0.5 for i in range(77)]
        if row % 2:
            xs = xs[::-1]
        for x in xs:
            out.append(f"G1 X{fmt(x)} Y{fmt(y)} Z{fmt(z_at(x, y))}")
        y += 1.5
        row += 1
    out += ["G0 Z10", "M30"]
    return "\n".join(out) + "\n"


def drill_and_mill() -> str:
    """Canned cycles and tool changes: T1 6 mm end mill faces the top 1 mm and mills a 20 × 10 pocket;
    T2 a 5 mm drill (118°) spots four holes with G81 and pecks them with G83 (Fanuc style)."""
    out = ["%", "O1002", "(face, pocket, drill; Fanuc/Haas style)", "G21 G90 G17 G94 G40 G49 G80",
           "T1 M6", "S9000 M3", "G54", "G0 X-4 Y2 Z10", "G43 Z10 H1", "G0 Z2", "G1 Z-1 F400"]
    y = 2.0
    while y <= 38.0:
        out += [f"G1 X64 Y{fmt(y)} F1200", f"G1 Y{fmt(y + 4)}", "G1 X-4"]
        y += 8.0
    out += ["G0 Z2", "G0 X23 Y15", "G1 Z-4 F300"]
    for k in range(4):
        d = 1.0 + 1.0 * k
        out += [f"G1 X{fmt(20 + d)} Y{fmt(15 + d)} F900", f"X{fmt(40 - d)}", f"Y{fmt(25 - d)}", f"X{fmt(20 + d)}",
                f"Y{fmt(15 + d)}"]
    out += ["G0 Z10", "M5", "G28 G91 Z0.", "G90", "T2 M6", "S3000 M3", "G0 X10 Y10 Z10", "G43 Z10 H2",
            "G98 G81 X10 Y10 Z-2 R2 F200", "X50", "Y30", "X10", "G80",
            "G98 G83 X10 Y10 Z-12 R2 Q3 F150", "X50", "Y30", "X10", "G80",
            "G0 Z10", "M5", "G28 G91 Z0.", "G90", "M30", "%"]
    return "\n".join(out) + "\n"


def offset_pocket() -> str:
    """A closed 40 × 30 mm pocket with R4 corners, 6 mm deep, cleared with the offset (contour-parallel)
    pattern as Fusion's 2D Pocket and FreeCAD's Pocket Shape (Offset) post it, 6 mm 3-flute in Al 6061:
    per 2 mm step-down a helical ramp (2°, 5 mm path diameter, G3 with Z in half turns) at the centre, a
    centre pass, then rings offset by 2.4 mm (40 % stepover) from the centre out, climb (counter-clockwise
    with M3), each joined to the next by a straight step; the last ring follows the wall, its R1
    tool-centre corners as arcs. One feed for the ramp, one for the rings; a retract between levels.
    Words are modal as a Fusion post writes them: G1 and unchanged coordinates are left out."""
    out = header("2D pocket, offset pattern, 6 mm 3F flat, Al 6061", 1, 9000)
    cx, cy, rh, ae = 30.0, 25.0, 2.5, 2.4
    wall_x, wall_y, corner = 17.0, 12.0, 1.0  # tool-centre half-sizes and corner radius at the wall (R 3 mm)
    rings = [(wall_x - k * ae, wall_y - k * ae) for k in range(5, -1, -1)]  # centre out; the first is a line
    pitch = 2 * math.pi * rh * math.tan(math.radians(2.0))  # depth per helix turn (mm)
    last: dict[str, str] = {}

    def move(g: str, feed: int | None = None, **axes: float) -> None:
        """One block with only the words that change (G1 is modal; arcs always carry I and J)."""
        words = [g] if (last.get("G") != g or g != "G1") else []
        for k, v in axes.items():
            if k in "IJ" or last.get(k) != fmt(v):
                words.append(f"{k}{fmt(v)}")
                last[k] = fmt(v)
        if feed is not None and last.get("F") != str(feed):
            words.append(f"F{feed}")
            last["F"] = str(feed)
        last["G"] = g
        out.append(" ".join(words))

    def ring(ax: float, ay: float, r: float) -> None:
        """A tool-centre ring of half-sizes ax, ay and corner radius r (0: sharp), counter-clockwise from
        (ax, 0) back to it: per side its end, then the corner arc's end and centre (I, J)."""
        for sx, sy, ex, ey, i, j in ((ax, ay - r, ax - r, ay, -r, 0), (-ax + r, ay, -ax, ay - r, 0, -r),
                                     (-ax, -ay + r, -ax + r, -ay, r, 0), (ax - r, -ay, ax, -ay + r, 0, r)):
            move("G1", X=cx + sx, Y=cy + sy)
            if r:
                move("G3", X=cx + ex, Y=cy + ey, I=i, J=j)
        move("G1", X=cx + ax, Y=cy)

    for z_top, z in ((0.0, -2.0), (-2.0, -4.0), (-4.0, -6.0)):
        # to the helix start, down to the ramp clearance 0.5 mm above the last floor, then the helix
        out += [f"G0 X{fmt(cx + rh)} Y{fmt(cy)}"] + (["Z5"] if z_top == 0 else [])
        last.update(G="G0", X=fmt(cx + rh), Y=fmt(cy), Z="5")
        move("G1", 500, Z=z_top + 0.5)
        zh, side = z_top + 0.5, 1.0
        while True:
            zh = max(zh - pitch / 2, z)
            move("G3", 500, X=cx - side * rh, Y=cy, Z=zh, I=-side * rh, J=0)
            side = -side
            if zh <= z:
                break
        move("G3", X=cx - side * rh, Y=cy, I=-side * rh, J=0)  # a flat half turn at the floor
        lx = rings[0][0]
        move("G1", 1000, X=cx + lx)  # the centre pass: out to the line's end, back, and out again
        move("G1", X=cx - lx)
        move("G1", X=cx + lx)
        for ax, ay in rings[1:]:
            move("G1", X=cx + ax)  # the step out onto the next ring
            ring(ax, ay, corner if ax == wall_x else 0.0)
        out.append("G0 Z5")
    out += ["G0 Z10", "M30"]
    return "\n".join(out) + "\n"


def sawcut_facing() -> str:
    """Facing the saw-cut top of an AISI 1045 block (200 × 120 mm; its top 1.0–4.5 mm above Z0, see the
    job's stock.py) to Z0 in one pass per row, as Fusion's Face and FreeCAD's MillFace (zig-zag) post it:
    a 63 mm square-shoulder face mill with 5 inserts, rows along X at a Y stepover spread evenly so the
    cutter overhangs each long side by 10 % of its diameter (3 rows, 34.8 mm apart), each row run 5 mm
    past the block (pass extension), the cutter taken down to Z0 in the air beside the block at the plunge
    feed and stepped over outside it at the cutting feed; one cutting feed for the whole operation."""
    out = header("face saw-cut top, 63 mm 5-insert face mill, steel 1045", 1, 1000)
    length, width, radius, overhang, extension = 200.0, 120.0, 31.5, 6.3, 5.0
    y_first, y_last = width + overhang - radius, radius - overhang
    rows = 1 + math.ceil((y_first - y_last) / (0.75 * 2 * radius))  # stepover at most 0.75 D
    ys = [y_first - k * (y_first - y_last) / (rows - 1) for k in range(rows)]
    x_in, x_out = -radius - extension, length + radius + extension
    out += [f"G0 X{fmt(x_in)} Y{fmt(ys[0])}", "G0 Z5", "G1 Z0 F250"]
    for k, y in enumerate(ys):
        if k:
            out.append(f"G1 Y{fmt(y)}")
        out.append(f"G1 X{fmt(x_out if k % 2 == 0 else x_in)}" + (" F500" if k == 0 else ""))
    out += ["G0 Z10", "M5", "M30"]
    return "\n".join(out) + "\n"


def forging_contour() -> str:
    """Roughing the drafted walls of a closed-die Al 6061 forging (its geometry in the job's stock.py) as
    Fusion's 2D Contour posts it with multiple depths: a 12 mm 3-flute end mill climbs clockwise round the
    finished 80 × 50 mm boss (corner R8) leaving 0.5 mm for the finishing pass, tool centre 6.5 mm off the
    part, at two depths of 10 mm (Z-10, Z-20); per depth a plunge in the air beside the part at the plunge
    feed, a 3 mm straight lead-in and a quarter-arc lead-in of radius 6 mm (0.5 D) onto the middle of the
    -Y wall, the loop, a quarter-arc lead-out, and a retract. One cutting feed for both depths."""
    out = header("OP20 rough boss walls, 12 mm 3F flat, Al 6061 forging", 1, 10000)
    cx, cy, hx, hy, r = 55.0, 40.0, 40.0 + 6.5, 25.0 + 6.5, 8.0 + 6.5  # tool-centre loop (mm)
    y0, lead = cy - hy, 6.0
    for z in (-10.0, -20.0):
        out += [f"G0 X{fmt(cx + lead)} Y{fmt(y0 - lead - 3)}"] + (["G0 Z5"] if z == -10.0 else [])
        out += [f"G1 Z{fmt(z)} F1000",
                f"G1 Y{fmt(y0 - lead)} F3000", f"G3 X{fmt(cx)} Y{fmt(y0)} I{fmt(-lead)} J0",
                f"G1 X{fmt(cx - hx + r)}", f"G2 X{fmt(cx - hx)} Y{fmt(cy - hy + r)} I0 J{fmt(r)}",
                f"G1 Y{fmt(cy + hy - r)}", f"G2 X{fmt(cx - hx + r)} Y{fmt(cy + hy)} I{fmt(r)} J0",
                f"G1 X{fmt(cx + hx - r)}", f"G2 X{fmt(cx + hx)} Y{fmt(cy + hy - r)} I0 J{fmt(-r)}",
                f"G1 Y{fmt(cy - hy + r)}", f"G2 X{fmt(cx + hx - r)} Y{fmt(y0)} I{fmt(-r)} J0",
                f"G1 X{fmt(cx)}", f"G3 X{fmt(cx - lead)} Y{fmt(y0 - lead)} I0 J{fmt(-lead)}", "G0 Z5"]
    out += ["G0 Z10", "M5", "M30"]
    return "\n".join(out) + "\n"


def thin_wall_finish() -> str:
    """Finishing both faces of a thin wall (40 mm long, 1.4 mm thick as roughed, 12 mm tall; 0.2 mm left
    on each face, finished 1.0 mm thick) with a 6 mm 3-flute end mill in one full-depth climb pass per
    face, the floor strip at Z-12 beside it cut by the tool's end; plunges in the air beyond the wall's
    ends; one programmed feed."""
    out = header("thin wall finish, 6 mm 3F flat, Al 6061", 1, 12000)
    r, allowance, depth = 3.0, 0.2, -12.0
    for name, y, x0, x1 in (("face Y-", allowance - r, 45.0, -5.0), ("face Y+", 1.4 - allowance + r, -5.0, 45.0)):
        out += [f"(finish {name})", f"G0 X{fmt(x0)} Y{fmt(y)}", "G0 Z2", f"G1 Z{fmt(depth)} F600",
                f"G1 X{fmt(x1)} F1440", "G0 Z10"]
    out += ["M5", "M30"]
    return "\n".join(out) + "\n"


PROGRAMS = {"adaptive_pocket": adaptive_pocket, "slotting": slotting, "ball_roughing": ball_roughing,
            "drill_and_mill": drill_and_mill, "offset_pocket": offset_pocket,
            "sawcut_facing": sawcut_facing, "forging_contour": forging_contour,
            "thin_wall_finish": thin_wall_finish}

if __name__ == "__main__":
    for name, make in PROGRAMS.items():
        (HERE / name).mkdir(exist_ok=True)
        (HERE / name / "program.nc").write_text(make())
        print(name, len(make().splitlines()), "lines")
