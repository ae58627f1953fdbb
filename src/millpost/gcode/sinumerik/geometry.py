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
