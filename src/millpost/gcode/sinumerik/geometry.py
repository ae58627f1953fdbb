"""Sinumerik frames and arcs by opening angle, as RS-274 words.

Frames (FB "Frames: programmable zero offset (TRANS, ATRANS)"): TRANS X Y Z replaces the programmable
frame by that offset, ATRANS adds to it; TRANS, ROT, SCALE or MIRROR alone clear it. The offset is kept
in #2000..#2002 (program units) and added to every absolute value of a program that sets one (so the
moves stay in the workpiece frame the stock is in, which a G52 would leave). ROT/AROT (FB "Programmable
rotation (ROT, AROT)") about Z: the angle in #2003; ROT replaces the frame (offsets cleared), AROT is
composed after it (about its origin), TRANS clears the rotation, ATRANS offsets are along the rotated
axes; a point p of the frame is T + R(a)·p in the workpiece. Scaling and mirroring with values are
refused.

Arcs with an opening angle (FB "Circular interpolation with opening angle and center point (AR)"):
``G2/G3 X.. Y.. AR=a`` (end point: centre on the chord's bisector, left of it for G3 when a < 180°) or
``G2/G3 I.. J.. AR=a`` (centre: the end is the start turned by a, clockwise for G2), written through
the start point #5420..#5422. In G17 the axes are X, Y (I, J); G18 Z, X (K, I); G19 Y, Z (J, K).
"""

from __future__ import annotations

FRAME_BASE = 2000  # #2000..#2002: the programmable offset (X, Y, Z)
ROTATION = 2003  # #2003: the programmable rotation about Z (degrees, counter-clockwise seen from +Z)
FRAMES = ("TRANS", "ATRANS", "ROT", "AROT", "SCALE", "ASCALE", "MIRROR", "AMIRROR")
PLANES = {17: (("X", "Y"), ("I", "J")), 18: (("Z", "X"), ("K", "I")), 19: (("Y", "Z"), ("J", "K"))}
_POSITION = {"X": 5420, "Y": 5421, "Z": 5422}


def frame_words(kind: str, offsets: dict[str, str], rotated: bool = False) -> list[str] | None:
    """The words of a TRANS/ATRANS block or a frame cleared (`offsets`: axis → NGC value); None when it
    cannot be modelled. In a program with rotations (`rotated`), TRANS also clears the rotation (it
    replaces the whole programmable frame) and ATRANS offsets are along the rotated axes."""
    if kind in ("TRANS", "ROT", "SCALE", "MIRROR") and not offsets:
        offsets, kind = {}, "TRANS"
    if kind not in ("TRANS", "ATRANS"):
        return None
    if kind == "ATRANS" and rotated:
        x, y = offsets.get("X", "0"), offsets.get("Y", "0")
        c, s = f"COS[#{ROTATION}]", f"SIN[#{ROTATION}]"
        offsets = {**offsets, "X": f"[{c}*[{x}]-{s}*[{y}]]", "Y": f"[{s}*[{x}]+{c}*[{y}]]"}
    words = []
    for k, axis in enumerate("XYZ"):
        old = f"#{FRAME_BASE + k}"
        value = offsets.get(axis, "0" if kind == "TRANS" else None)
        if value is not None:
            words.append(f"{old}={value if kind == 'TRANS' else f'[{old}+{value}]'}")
    return words + ([f"#{ROTATION}=0"] if rotated and kind == "TRANS" else [])


def rotation_words(kind: str, angle: str) -> list[str]:
    """ROT (replaces the programmable frame: offsets cleared, rotation `angle`) or AROT (the rotation
    composed after the current frame: about its origin, angles added), about Z."""
    if kind == "AROT":
        return [f"#{ROTATION}=[#{ROTATION}+{angle}]"]
    return [f"#{FRAME_BASE + k}=0" for k in range(3)] + [f"#{ROTATION}={angle}"]


def _local(axis: int) -> str:
    """The current point's X (axis 0) or Y (1) in the rotated frame: R(-a)·(P - T)."""
    c, s = f"COS[#{ROTATION}]", f"SIN[#{ROTATION}]"
    dx, dy = f"[#5420-#{FRAME_BASE}]", f"[#5421-#{FRAME_BASE + 1}]"
    return f"[{c}*{dx}+{s}*{dy}]" if axis == 0 else f"[{c}*{dy}-{s}*{dx}]"


def rotated_point(targets: dict[str, tuple[str, bool]], absolute: bool) -> list[str]:
    """The X/Y words of a move programmed in the rotated frame (`targets`: axis → (NGC value, absolute
    or incremental), missing axes staying at the current point): its end T + R(a)·local in the
    workpiece frame, written absolute in G90 or from the current point in G91."""
    local = []
    for k, axis in enumerate("XY"):
        value, is_abs = targets.get(axis, ("0", False))
        local.append(f"[{value}]" if is_abs else f"[{_local(k)}+[{value}]]")
    c, s = f"COS[#{ROTATION}]", f"SIN[#{ROTATION}]"
    ends = (f"[#{FRAME_BASE}+{c}*{local[0]}-{s}*{local[1]}]", f"[#{FRAME_BASE + 1}+{s}*{local[0]}+{c}*{local[1]}]")
    return [f"{a}{e if absolute else f'[{e}-#{5420 + k}]'}" for k, (a, e) in enumerate(zip("XY", ends))]


def rotated_centre(centre: dict[str, tuple[str, bool]]) -> list[str]:
    """The I/J words of an arc centre programmed in the rotated frame (`centre`: I/J → (NGC value,
    absolute I=AC(..) or offset from the start)): the offset turned by the rotation."""
    rel = []
    for k, name in enumerate("IJ"):
        value, is_abs = centre.get(name, ("0", False))
        rel.append(f"[[{value}]-{_local(k)}]" if is_abs else f"[{value}]")
    c, s = f"COS[#{ROTATION}]", f"SIN[#{ROTATION}]"
    return [f"I[{c}*{rel[0]}-{s}*{rel[1]}]", f"J[{s}*{rel[0]}+{c}*{rel[1]}]"]


def arc_by_angle(plane: int, angle: str, ccw: bool, absolute: bool, ends: dict[str, str],
                 centre: dict[str, str]) -> list[str]:
    """The plane's axis and centre words of an arc with opening angle `angle` (degrees) from its end
    point (`ends`, axis → NGC value as programmed) or its centre (`centre`, I/J/K → incremental NGC value)."""
    (p1, p2), (c1, c2) = PLANES[plane]
    s = "" if ccw else "-"
    start = {a: f"#{_POSITION[a]}" for a in (p1, p2)}
    if ends:
        d = {a: ("0" if a not in ends else f"[{ends[a]}-{start[a]}]" if absolute else ends[a]) for a in (p1, p2)}
        t = f"[2*TAN[[{angle}]/2]]"
        words = [f"{a}{ends[a]}" for a in (p1, p2) if a in ends]
        return words + [f"{c1}[{d[p1]}/2-{s}1*{d[p2]}/{t}]", f"{c2}[{d[p2]}/2+{s}1*{d[p1]}/{t}]"]
    i, j = centre.get(c1, "0"), centre.get(c2, "0")
    th = f"[{s}1*[{angle}]]"
    e1 = f"{i}-{i}*COS[{th}]+{j}*SIN[{th}]"
    e2 = f"{j}-{i}*SIN[{th}]-{j}*COS[{th}]"
    if absolute:
        e1, e2 = f"{start[p1]}+{e1}", f"{start[p2]}+{e2}"
    return [f"{p1}[{e1}]", f"{p2}[{e2}]", f"{c1}{i}", f"{c2}{j}"]


TANGENT = {"X": "#<_sin_tx>", "Y": "#<_sin_ty>", "Z": "#<_sin_tz>"}  # the last path element's end direction


def _deltas(plane: int, ends: dict[str, str], absolute: bool) -> tuple[str, str]:
    """The move's displacement along the plane's two axes (`ends`: axis → NGC value as programmed)."""
    (p1, p2), _ = PLANES[plane]
    return tuple("0" if a not in ends else f"[{ends[a]}-#{_POSITION[a]}]" if absolute else ends[a]
                 for a in (p1, p2))


def tangent_arc(plane: int, ends: dict[str, str], absolute: bool) -> list[str]:
    """The words of a CT arc: with D the displacement, T the previous element's end direction and N = T
    turned +90° in the plane, the centre is start + s·N with s = |D|² / (2 N·D) (equidistant from both
    ends, on the start's normal); counter-clockwise (G3) when N·D > 0, the centre left of T."""
    (p1, p2), (c1, c2) = PLANES[plane]
    d1, d2 = _deltas(plane, ends, absolute)
    n1, n2 = f"[-{TANGENT[p2]}]", TANGENT[p1]
    nd = f"[{n1}*{d1}+{n2}*{d2}]"
    s = f"[[{d1}*{d1}+{d2}*{d2}]/[2*{nd}]]"
    return [f"G[2+[{nd} GT 0]]", *(f"{a}{ends[a]}" for a in (p1, p2) if a in ends), f"{c1}[{s}*{n1}]",
            f"{c2}[{s}*{n2}]"]


def end_tangent(plane: int, words: list[str], absolute: bool, motion: int | None) -> list[str]:
    """Assignments of the plane's tangent parameters to a move's end direction, from its NGC `words`:
    a line's displacement; an arc's radius at the end (end - centre, the centre from its centre words or
    its R) turned +90° for G3, -90° for G2. `motion` None: a CIP/CT arc, its direction in its G[2+[c]]."""
    (p1, p2), (c1, c2) = PLANES[plane]

    def word(letter: str) -> str | None:
        return next((w[len(letter):] for w in words if w.startswith(letter) and not w[len(letter):][:1].isalpha()
                     and w[len(letter):][:1] not in ("", "=")), None)

    d1, d2 = _deltas(plane, {a: v for a in (p1, p2) if (v := word(a)) is not None}, absolute)
    if motion in (0, 1):
        return [f"{TANGENT[p1]}={d1}", f"{TANGENT[p2]}={d2}"]
    ccw = str(int(motion == 3)) if motion is not None else next(w[4:-1] for w in words if w.startswith("G[2+"))
    radius = word("R")
    if radius is not None and word(c1) is None and word(c2) is None:
        dd = f"[{d1}*{d1}+{d2}*{d2}]"
        h = f"[SQRT[ABS[[{radius}]*[{radius}]/{dd}-0.25]]]"
        side = f"[[2*{ccw}-1]*[{radius}]/ABS[{radius}]]"
        i, j = f"[{d1}/2-{side}*{h}*{d2}]", f"[{d2}/2+{side}*{h}*{d1}]"
    else:
        i, j = word(c1) or "0", word(c2) or "0"
    sign = f"[2*{ccw}-1]"
    return [f"{TANGENT[p1]}=[-{sign}*[{d2}-{j}]]", f"{TANGENT[p2]}=[{sign}*[{d1}-{i}]]"]
