"""A job's settings, typed: the `[limits]` table of a job file (`JobSettings`).

The table holds the user's limits (deflection, feed caps, jerk, the tool's safety factor, how far a plunge
may speed up, how much slower a program may get) and the run's settings (sampling step, force model,
which limits lower a feed, feed step, solver, spindle speeds, air clearance). The job file writes feeds
in mm/min (`..._mm_min` keys); the code reads them in mm/s (`feed_max_mm_s`, ...).

Every number must be finite and inside its stated range (`RANGES`, both ends included): outside it a
value is a slip (a unit or a digit wrong), not a wish. ds_mm below 1 µm or above 5 mm cannot resolve a
cut; a deflection budget of 5 mm or a feed of 1000 m/min is no limit at all.
"""

from __future__ import annotations

from dataclasses import Field, dataclass, field, fields
from typing import Any

from .config import is_number
from .errors import ConfigError
from .registry import plugins


def _ranged(default: float | None, lo: float, hi: float, unit: str = "") -> Any:
    """A numeric setting in [lo, hi]; `unit` follows the range in the refusal."""
    return field(default=default, metadata={"range": (lo, hi), "unit": unit})


def _choice(*names: str) -> Any:
    """A setting named by one of `names`, the first the default."""
    return field(default=names[0], metadata={"choices": names})


@dataclass(frozen=True)
class JobSettings:
    """The `[limits]` table of a job file: each key a field, its default where the file leaves it out.
    Checked on construction: a value outside its rule is a `ConfigError` naming `limits.<key>`."""

    deflection_mm: float | None = _ranged(None, 1e-4, 5.0)
    """Bound on the tool's deflection at the cut (mm); None: a rough bound by the tool's diameter."""
    feed_max_mm_min: float | None = _ranged(None, 1.0, 1e6)
    """Cap on every feed (mm/min, `feed_max_mm_s`); None: the machine's."""
    tool_safety_factor: float | None = _ranged(None, 1.0, 100.0)
    """Safety factor on the tool's bending, buckling and torsional strength; None: by its diameter and
    slenderness (`tools.beam.default_safety_factor`)."""
    ds_mm: float = _ranged(0.1, 1e-3, 5.0)
    """Resampling step along the toolpath (mm)."""
    model: str = field(default="mechanistic", metadata={"plugins": "force_models"})
    """The force model: a plugin of the group `force_models` (`millpost.registry`)."""
    jerk_mm_s3: float | None = _ranged(None, 1.0, 1e9)
    """Bound on the path jerk (mm/s³); None: none."""
    plunge_feed_max_mm_min: float | None = _ranged(None, 1.0, 1e6)
    """Cap on the feed of moves going down into material: plunges, drilling, ramps (mm/min,
    `plunge_feed_max_mm_s`); None: none."""
    plunge_raise_max: float = _ranged(2.0, 1.0, 100.0)
    """Those moves at most this × their programmed feed."""
    lower: str = _choice("hard", "all")
    """Which limits lower a programmed feed: the hard ones, or all (quality limits too)."""
    feed_step: float = _ranged(0.05, 0.0, 1.0, " (relative)")
    """Relative step between the F words written."""
    solver: str = _choice("auto", "clarabel")
    """The schedule's solver: chosen per segment, or Clarabel on every segment."""
    rpm: str = _choice("programmed", "optimize")
    """The spindle speeds: as programmed, or chosen per operation (`millpost.spindle_speed`)."""
    air_clearance_mm: float = _ranged(3.0, 0.0, 100.0)
    """Feed moves that cut nothing within this of the stock keep their programmed feed (mm)."""
    trust_cut_space: bool = False
    """False: a move going down below the stock's top keeps the plunge rules where the program cut before
    (a restart from a later line leaves that space uncut)."""
    air_feed_max_mm_min: float | None = _ranged(None, 1.0, 1e6)
    """Cap on feed moves through cut space below the stock's top (mm/min, `air_feed_max_mm_s`); None: the
    machine's maximum."""
    slower_max: float = _ranged(1.25, 1.0, 100.0)
    """Refuse an optimized program slower than this × the programmed one (unless --allow slower)."""

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            _check(f, value)
            if "range" in f.metadata and value is not None:
                object.__setattr__(self, f.name, float(value))

    @classmethod
    def from_table(cls, table: dict[str, Any], file: str) -> JobSettings:
        """The settings of a job file's `[limits]` table, its keys checked in the file's order (`file`
        names it in a refusal)."""
        known = {f.name: f for f in fields(cls)}
        for key, value in table.items():
            if key not in known:
                raise ConfigError(f"limits.{key}", value, f"unknown limit; known: {', '.join(known)}", file=file)
            _check(known[key], value, file)
        return cls(**table)

    @property
    def feed_max_mm_s(self) -> float | None:
        """`feed_max_mm_min` in mm/s."""
        return _mm_s(self.feed_max_mm_min)

    @property
    def plunge_feed_max_mm_s(self) -> float | None:
        """`plunge_feed_max_mm_min` in mm/s."""
        return _mm_s(self.plunge_feed_max_mm_min)

    @property
    def air_feed_max_mm_s(self) -> float | None:
        """`air_feed_max_mm_min` in mm/s."""
        return _mm_s(self.air_feed_max_mm_min)


RANGES: dict[str, tuple[float, float]] = {f.name: f.metadata["range"] for f in fields(JobSettings)
                                          if "range" in f.metadata}
"""The stated range of each numeric setting, both ends included."""


def _check(f: Field, value: object, file: str | None = None) -> None:
    """Refuse `value` for the setting `f` (a field of `JobSettings`) unless it keeps the field's rule."""
    if "plugins" in f.metadata:
        names = plugins(f.metadata["plugins"])
        ok, rule = isinstance(value, str) and value in names, f"one of {', '.join(sorted(names))}"
    elif "choices" in f.metadata:
        ok, rule = isinstance(value, str) and value in f.metadata["choices"], " or ".join(f.metadata["choices"])
    elif isinstance(f.default, bool):
        ok, rule = isinstance(value, bool), "must be true or false"
    else:
        lo, hi = f.metadata["range"]
        ok = value is None and f.default is None or is_number(value) and lo <= value <= hi
        rule = f"must be a number in [{lo:g}, {hi:g}]{f.metadata['unit']}"
    if not ok:
        raise ConfigError(f"limits.{f.name}", value, rule, file=file)


def _mm_s(feed_mm_min: float | None) -> float | None:
    """A feed in mm/min in mm/s; None stays None."""
    return None if feed_mm_min is None else feed_mm_min / 60.0
