"""The part as forged (closed die, Al 6061-T6), after OP10 faced its top to Z0: a boss on a web.

Finished boss (the part): 80 × 50 mm, X15–95 Y15–65, corner R8, vertical walls from Z0 down to the web.
The forging around it:
- web: 110 × 80 mm, X0–110 Y0–80, from Z-31 to its forged top at Z-21;
- boss: 1.5 mm machining allowance on the walls at the top (half sizes 41.5 × 26.5 mm at Z0), corner R12
  (a forging die's generous outside corner: less allowance at the corners than on the sides), 7° draft
  (outside walls of a closed-die forging, 5–7°: the allowance grows by tan 7° = 0.123 mm per mm of depth,
  to 4.1 mm at the web);
- die shift: the boss sits 0.8 mm off the part in +X (closed-die forgings are allowed about 0.5–1 mm of
  mismatch; the part is located from the web), so the +X wall carries 0.8 mm more and the -X wall 0.8 mm
  less;
- R5 fillet where the boss meets the web (forging fillet radii are several mm), extra material at the
  foot of the walls.
Work zero: the faced top, at the web's X0 Y0 corner. Lengths in mm."""

import math

from build123d import Axis, Box, Plane, Pos, RectangleRounded, extrude, fillet

WEB_TOP, WEB_BOTTOM = -21.0, -31.0
CENTRE_X, CENTRE_Y, SHIFT_X = 55.0, 40.0, 0.8
HALF_X, HALF_Y, CORNER_R = 41.5, 26.5, 12.0  # boss at Z0 (part 40 × 25 half sizes + 1.5 mm)
DRAFT_DEG, FOOT_FILLET_R = 7.0, 5.0


def stock():
    web = Pos(55.0, 40.0, (WEB_TOP + WEB_BOTTOM) / 2) * Box(110.0, 80.0, WEB_TOP - WEB_BOTTOM)
    grow = -WEB_TOP * math.tan(math.radians(DRAFT_DEG))  # the draft's offset at the web (mm)
    foot = RectangleRounded(2 * (HALF_X + grow), 2 * (HALF_Y + grow), CORNER_R + grow)
    boss = extrude(Plane.XY.offset(WEB_TOP).move(Pos(CENTRE_X + SHIFT_X, CENTRE_Y)) * foot, amount=-WEB_TOP,
                   taper=DRAFT_DEG)
    part = web + boss
    foot_edges = part.edges().filter_by_position(Axis.Z, WEB_TOP - 1e-6, WEB_TOP + 1e-6).filter_by(
        lambda e: abs(e.center().X - CENTRE_X - SHIFT_X) < HALF_X + grow + 1e-3
        and abs(e.center().Y - CENTRE_Y) < HALF_Y + grow + 1e-3)
    return fillet(foot_edges, FOOT_FILLET_R)
