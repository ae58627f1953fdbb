"""Sinumerik frames and arcs by opening angle, as RS-274 words.

Frames (FB "Frames: programmable zero offset (TRANS, ATRANS)"): TRANS X Y Z replaces the programmable
frame by that offset, ATRANS adds to it; TRANS, ROT, SCALE or MIRROR alone clear it. The offset is kept
in #2000..#2002 (program units) and added to every absolute value of a program that sets one (so the
moves stay in the workpiece frame the stock is in, which a G52 would leave). Rotation about Z (ROT,
AROT), scaling (SCALE, ASCALE) and mirroring (MIRROR, AMIRROR) in X/Y make the frame's matrix M, kept
as M - I in #2003..#2006 (0 before any frame: the identity): a point p of the frame is T + M·p in the
workpiece frame. ROT, SCALE, MIRROR and TRANS replace the programmable frame (offsets and matrix);
AROT, ASCALE, AMIRROR compose after it (M ← M·A, about its origin) and ATRANS offsets go through M.

Arcs with an opening angle (FB "Circular interpolation with opening angle and center point (AR)"):
``G2/G3 X.. Y.. AR=a`` (end point: centre on the chord's bisector, left of it for G3 when a < 180°) or
``G2/G3 I.. J.. AR=a`` (centre: the end is the start turned by a, clockwise for G2), written through
the start point #5420..#5422. In G17 the axes are X, Y (I, J); G18 Z, X (K, I); G19 Y, Z (J, K).
"""

from __future__ import annotations

FRAME_BASE = 2000  # #2000..#2002: the programmable offset (X, Y, Z)
FRAMES = ("TRANS", "ATRANS", "ROT", "AROT", "SCALE", "ASCALE", "MIRROR", "AMIRROR")
PLANES = {17: (("X", "Y"), ("I", "J")), 18: (("Z", "X"), ("K", "I")), 19: (("Y", "Z"), ("J", "K"))}
_POSITION = {"X": 5420, "Y": 5421, "Z": 5422}


MATRIX = 2003  # #2003..#2006: the frame's X/Y matrix minus the identity (m11-1, m12, m21, m22-1)
_M = (f"[1+#{MATRIX}]", f"#{MATRIX + 1}", f"#{MATRIX + 2}", f"[1+#{MATRIX + 3}]")
DET = f"[{_M[0]}*{_M[3]}-{_M[1]}*{_M[2]}]"  # < 0: the frame mirrors (G2/G3 and G41/G42 swap)


def frame_words(kind: str, offsets: dict[str, str], linear: bool = False) -> list[str] | None:
    """The words of a TRANS/ATRANS block or a frame cleared (`offsets`: axis → NGC value); None when it
    cannot be modelled. In a program with rotation, scaling or mirroring (`linear`), TRANS also resets
    the matrix (it replaces the whole programmable frame) and ATRANS offsets go through the matrix."""
    if kind in ("TRANS", "ROT", "SCALE", "MIRROR") and not offsets:
        offsets, kind = {}, "TRANS"
    if kind not in ("TRANS", "ATRANS"):
        return None
    if kind == "ATRANS" and linear:
        x, y = offsets.get("X", "0"), offsets.get("Y", "0")
        offsets = {**offsets, "X": f"[{_M[0]}*[{x}]+{_M[1]}*[{y}]]", "Y": f"[{_M[2]}*[{x}]+{_M[3]}*[{y}]]"}
    words = []
    for k, axis in enumerate("XYZ"):
        old = f"#{FRAME_BASE + k}"
        value = offsets.get(axis, "0" if kind == "TRANS" else None)
        if value is not None:
            words.append(f"{old}={value if kind == 'TRANS' else f'[{old}+{value}]'}")
    return words + ([f"#{MATRIX + k}=0" for k in range(4)] if linear and kind == "TRANS" else [])


def matrix_words(kind: str, a: tuple[str, str, str, str]) -> list[str]:
    """ROT/SCALE/MIRROR (substitutional: the programmable frame replaced by the matrix `a` = (a11, a12,
    a21, a22), offsets cleared) or AROT/ASCALE/AMIRROR (additive: composed after the current frame,
    M ← M·A, about its origin; NGC reads a line's parameters before it sets any)."""
    if not kind.startswith("A"):
        return [f"#{FRAME_BASE + k}=0" for k in range(3)] + [
            f"#{MATRIX + k}=[{v}{'-1' if k in (0, 3) else ''}]" for k, v in enumerate(a)]
    m = _M
    prod = (f"{m[0]}*{a[0]}+{m[1]}*{a[2]}", f"{m[0]}*{a[1]}+{m[1]}*{a[3]}",
            f"{m[2]}*{a[0]}+{m[3]}*{a[2]}", f"{m[2]}*{a[1]}+{m[3]}*{a[3]}")
    return [f"#{MATRIX + k}=[{v}{'-1' if k in (0, 3) else ''}]" for k, v in enumerate(prod)]


def rotation(angle: str) -> tuple[str, str, str, str]:
    """The matrix of a rotation by `angle` degrees about Z (counter-clockwise seen from +Z)."""
    c, s = f"COS[{angle}]", f"SIN[{angle}]"
    return c, f"[-{s}]", s, c


def _local(axis: int) -> str:
    """The current point's X (axis 0) or Y (1) in the frame: M⁻¹·(P - T)."""
    dx, dy = f"[#5420-#{FRAME_BASE}]", f"[#5421-#{FRAME_BASE + 1}]"
    m = _M
    return f"[[{m[3]}*{dx}-{m[1]}*{dy}]/{DET}]" if axis == 0 else f"[[{m[0]}*{dy}-{m[2]}*{dx}]/{DET}]"


def framed_point(targets: dict[str, tuple[str, bool]], absolute: bool) -> list[str]:
    """The X/Y words of a move programmed in the frame (`targets`: axis → (NGC value, absolute or
    incremental), missing axes staying at the current point): its end T + M·local in the workpiece
    frame, written absolute in G90 or from the current point in G91."""
    local = []
    for k, axis in enumerate("XY"):
        value, is_abs = targets.get(axis, ("0", False))
        local.append(f"[{value}]" if is_abs else f"[{_local(k)}+[{value}]]")
    m = _M
    ends = (f"[#{FRAME_BASE}+{m[0]}*{local[0]}+{m[1]}*{local[1]}]",
            f"[#{FRAME_BASE + 1}+{m[2]}*{local[0]}+{m[3]}*{local[1]}]")
    return [f"{a}{e if absolute else f'[{e}-#{5420 + k}]'}" for k, (a, e) in enumerate(zip("XY", ends))]


def framed_centre(centre: dict[str, tuple[str, bool]]) -> list[str]:
    """The I/J words of an arc centre programmed in the frame (`centre`: I/J → (NGC value, absolute
    I=AC(..) or offset from the start)): the offset through the matrix."""
    rel = []
    for k, name in enumerate("IJ"):
        value, is_abs = centre.get(name, ("0", False))
        rel.append(f"[[{value}]-{_local(k)}]" if is_abs else f"[{value}]")
    m = _M
    return [f"I[{m[0]}*{rel[0]}+{m[1]}*{rel[1]}]", f"J[{m[2]}*{rel[0]}+{m[3]}*{rel[1]}]"]


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
