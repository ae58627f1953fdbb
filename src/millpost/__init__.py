"""millpost: a physics-aware post step for CNC milling programs.

Data flows one way: G-code → toolpath → engagement → forces → schedule → G-code.
Units inside: mm, s, N, W, N·m, rad; feeds in mm/min and speeds in rpm only where customary.
"""

__version__ = "0.1.0"
