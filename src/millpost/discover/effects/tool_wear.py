"""tool_wear: the cutting coefficients grow as the edge wears, with the engaged path length L (m) the tool
has cut so far: K(L) = K·(1 + w·L), so every cutting channel reads its cutting share × (1 + w·L).
Parameter w (per m of cut). Channels: forces and spindle power."""

from __future__ import annotations

from .base import Context, Effect, Variant, cutting_channels


class ToolWear(Effect):
    name = "tool_wear"
    channels = ("fx_N", "fy_N", "fz_N", "spindle_power_W")
    meaning = "cutting coefficients rising with cut length"
    positive = ("wear_per_m",)

    def variants(self, ctx: Context):
        chans = cutting_channels(ctx)
        length = ctx.rows.features["cut_length_m"]
        if chans and length.max() > 0:
            yield Variant({}, {c: {self.param("wear_per_m"): ctx.cutting(c) * length} for c in chans})
