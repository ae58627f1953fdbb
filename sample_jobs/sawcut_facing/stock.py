"""The blank as it comes off the bandsaw: an AISI 1045 block 200 × 120 mm (X × Y), bottom at Z-30, whose
top is the saw cut. Blanks are ordered with about +3 mm on each face; this cut ran out of square, so the
top is a tilted plane, 1.0 mm above the finished top (Z0) at the corner X0 Y0 and 4.5 mm above it at X200
Y120 (2.5 mm over the 200 mm length, 1.0 mm over the 120 mm width: a blade that drifted 1.25 % and
0.8 %). Work zero: the finished top at the block's X0 Y0 corner. Lengths in mm."""

from build123d import Box, Keep, Plane, Pos, Vector, split

LENGTH, WIDTH, BOTTOM = 200.0, 120.0, -30.0
TOP_AT_ORIGIN, RISE_X, RISE_Y = 1.0, 2.5, 1.0  # saw-cut top z = 1.0 + 2.5·x/200 + 1.0·y/120 (mm)


def stock():
    block = Pos(LENGTH / 2, WIDTH / 2, BOTTOM / 2 + 5.0) * Box(LENGTH, WIDTH, 10.0 - BOTTOM)
    normal = Vector(-RISE_X / LENGTH, -RISE_Y / WIDTH, 1.0)
    return split(block, bisect_by=Plane(origin=(0, 0, TOP_AT_ORIGIN), z_dir=normal), keep=Keep.BOTTOM)
