"""axis_friction: Coulomb and viscous friction of a feed axis in its motor current,
i_f = k_c·sgn(v) + k_v·v (machine.py's drive model, in current units; k_c, k_v ≥ 0: friction opposes
the motion). Parameters per logged axis:
coulomb_<x>_A, viscous_<x>_A_per_mm_s. Channels: ix_A, iy_A, iz_A."""

from __future__ import annotations

import numpy as np

from ...measure.alignment import STILL_MM_S
from .base import Context, Effect, Variant


class AxisFriction(Effect):
    name = "axis_friction"
    channels = ("ix_A", "iy_A", "iz_A")
    meaning = "Coulomb + viscous friction in axis motor current"
    bounded = ("coulomb_", "viscous_")   # friction opposes motion: neither term below 0

    def variants(self, ctx: Context):
        v = ctx.rows.features["velocity_mm_s"]
        chans = ctx.measured(self.channels)
        if chans:
            # at rest the friction's sign is undetermined (and a speed derived from logged positions is noise)
            moving = np.abs(v) > STILL_MM_S
            yield Variant({}, {c: {self.param(f"coulomb_{c[1]}_A"): np.sign(v[:, k]) * moving[:, k],
                                   self.param(f"viscous_{c[1]}_A_per_mm_s"): v[:, k]}
                               for c in chans for k in [self.channels.index(c)]})
