"""Klartext programs shared by the Heidenhain tests of several folders."""

# slots and a contour (lines, CC/C, CR, CT, IX/IY), 6 mm 3-flute flat, Al 6061, in a 60 x 40 x 10 blank
SLOTS = """0 BEGIN PGM SLOTS MM
1 BLK FORM 0.1 Z X+0 Y+0 Z-10
2 BLK FORM 0.2 X+60 Y+40 Z+0
3 ; slots and contour, 6 mm 3F flat
4 TOOL CALL 1 Z S9000
5 CYCL DEF 32.0 TOLERANCE
6 CYCL DEF 32.1 T0.05
7 L Z+10 R0 FMAX M3
8 L X-5 Y+8 R0 FMAX
9 L Z-1.5 F300
10 L X+65 F700 M8 ; slot
11 L Z+2 FMAX
12 L X-5 Y+20 FMAX
13 L Z-3
14 L IX+70 IY+0.5
15 L Z+10 FMAX
16 L X+30 Y-2 FMAX
17 L Z-4 F300
18 L X+52 F900
19 CC X+52 Y+8
20 C X+62 Y+8 DR+
21 L Y+32
22 CR X+52 Y+42 R+10 DR+
23 L X+8
24 CT X-2 Y+32
25 L Y+8
26 CC X+8 Y+8
27 C X+8 Y-2 DR+
28 L X+30
29 L Z+10 FMAX M5
30 M30
31 END PGM SLOTS MM
"""
