"""Sinumerik frames and arcs by opening angle, as RS-274 words.

Frames (FB "Frames: programmable zero offset (TRANS, ATRANS)"): TRANS X Y Z replaces the programmable
frame by that offset, ATRANS adds to it; TRANS, ROT, SCALE or MIRROR alone clear it. The offset is kept
in #2000..#2002 (program units) and added to every absolute value of a program that sets one (so the
moves stay in the workpiece frame the stock is in, which a G52 would leave). Rotation, scaling and
mirroring with values are refused.

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


def frame_words(kind: str, offsets: dict[str, str]) -> list[str] | None:
    """The words of a frame block (`offsets`: axis → NGC value); None when it cannot be modelled."""
    if kind in ("TRANS", "ROT", "SCALE", "MIRROR") and not offsets:
        offsets, kind = {}, "TRANS"
    if kind not in ("TRANS", "ATRANS"):
        return None
    words = []
    for k, axis in enumerate("XYZ"):
        old = f"#{FRAME_BASE + k}"
        value = offsets.get(axis, "0" if kind == "TRANS" else None)
        if value is not None:
            words.append(f"{old}={value if kind == 'TRANS' else f'[{old}+{value}]'}")
    return words


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
