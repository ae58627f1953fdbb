"""Emission: from the schedule's solution (v(s), mm/s) to the program written with new F words.

- `policy`: the F-word policy — the emission limit from the schedule (`emission_limit`, `hold_runs`),
  per-move fragments (`piecewise_feeds`, `Fragment`), settling, clustering and reachable peaks;
- `blends`: the controller's blend arcs against the F words (`blend_excess`, `blend_limit`,
  `run_limit`) and the emission passes that keep them within the limit (`emit_within`, its
  `Emission`; `baseline_within` for the honest baseline);
- `write`: writing the program back (`FeedPlan`, `write_feeds`, split moves, number style,
  `cycle_feeds`, `replace_numbers`);
- `pieces`: the emitted program's moves against the original's (`emitted_positions`,
  `original_arc_length`, `pieces_of_moves`).
"""

from .blends import (BLEND_PASSES, Emission, baseline_within, blend_excess, blend_limit, emit_programmed,
                     emit_within, run_limit)
from .pieces import emitted_positions, original_arc_length, pieces_of_moves
from .policy import Fragment, cluster, emission_limit, hold_runs, piecewise_feeds, reachable, settle
from .write import (SNAP_TO_PROGRAMMED, FeedPlan, computed, cycle_feeds, replace_numbers, split_decimals,
                    whole_moves, write_feeds)

__all__ = ["BLEND_PASSES", "SNAP_TO_PROGRAMMED", "Emission", "FeedPlan", "Fragment", "baseline_within",
           "blend_excess", "blend_limit", "cluster", "computed", "cycle_feeds", "emission_limit",
           "emit_programmed", "emit_within", "emitted_positions", "hold_runs", "original_arc_length",
           "piecewise_feeds", "pieces_of_moves", "reachable", "replace_numbers", "run_limit", "settle",
           "split_decimals", "whole_moves", "write_feeds"]
