"""Cutting-force models. Both take an `Engagement` (per-sample, per-slice immersion arcs), a feed per
tooth and a spindle speed, and return `Loads`; `linear_loads` gives the affine-in-feed form the feed
scheduler needs, `fit` identifies coefficients from measurements."""

from .base import (LinearLoads, Loads, NotFittedError, chip_thinning_factor, given_cut, immersion, max_chip_mm,
                   mean_chip_mm)
from .kienzle import Kienzle
from .mechanistic import COEF_NAMES, Measurements, Mechanistic

__all__ = ["COEF_NAMES", "Kienzle", "LinearLoads", "Loads", "Measurements", "Mechanistic", "NotFittedError",
           "chip_thinning_factor", "given_cut", "immersion", "max_chip_mm", "mean_chip_mm"]
