"""The controller model's vocabulary: its settings (`ControllerModel`), the path modes a program runs
in (`PathModes`), and what a planner model is (`Planner`) and queues (`Queue`). Each controller kind's
planner registers itself where it is defined (`Planner.register`: `grbl`, `linuxcnc`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np

from ..errors import ConfigError
from ..toolpath import Toolpath

EXACT_PATH, EXACT_STOP = -1.0, -2.0  # path modes in a blend-tolerance array: G61, G61.1


@dataclass(frozen=True)
class PathModes:
    """Per move, the path control LinuxCNC runs it in. blend_mm: the blend tolerance (G64 P, mm; 0 for a
    G64 without P) or EXACT_PATH (G61: stop at corners) or EXACT_STOP (G61.1: stop after every move).
    merge_mm: the naive-CAM tolerance (G64 Q, mm; P when Q is absent, 0 for a plain G64, in G61/G61.1,
    in canned cycles and on a controller that merges nothing, `Planner.merges_naive_cam`):
    consecutive straight feeds whose points lie this close to one line are sent to the planner as that
    one line (`naive_cam_chains`). flush: a command before the move ends the chain
    being merged (a pause, a spindle speed, an offset, a path mode, an operator message)."""

    blend_mm: np.ndarray
    merge_mm: np.ndarray
    flush: np.ndarray

    @classmethod
    def uniform(cls, n: int, model: ControllerModel) -> PathModes:
        """The controller's own modes on every move."""
        return cls(np.full(n, model.blend_tolerance_mm), np.full(n, model.naive_cam_mm), np.zeros(n, bool))


@dataclass
class Queue:
    """The blocks a planner runs, in path order (lengths mm, speeds mm/s, accelerations mm/s²): per
    block its length, top speed, acceleration, the program move and the fraction of it where the block
    ends, and whether it may run as one linear ramp (`LinuxCNCPlanner.timed`); the squared speed caps at
    the n+1 junctions (0 at the ends and where the motion stops). cuts (m, 4): (block, fraction of it,
    move, fraction of that move) where a block passes from one program move onto the next
    (`run.cut_blocks`).
    blends (k, 3): the blend arcs, each the program's arc length (mm) where it starts and ends and the
    index of its block."""

    length: np.ndarray
    vnom: np.ndarray
    acc: np.ndarray
    vj2: np.ndarray
    move: np.ndarray
    u_end: np.ndarray
    may_ramp: np.ndarray
    cuts: np.ndarray = field(default_factory=lambda: np.zeros((0, 4)))
    blends: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


class Planner(ABC):
    """A controller's motion planner: the behaviour of its kind (the numbers are the `ControllerModel`'s).
    lookahead_blocks: how many blocks it plans ahead (the model's default depth); runs_arcs_whole: an
    arc is one segment the planner itself clamps at √(a_n·r) (else chords that keep the F word, so the
    F word carries the centripetal cap); blends_corners: it passes corners on blend arcs at up to the
    faster move's feed (`corner_speeds`, `blend_zones`; else grbl's junction deviation, never above the
    slower block's feed); merges_naive_cam: its controller sends consecutive straight feeds within the
    naive-CAM tolerance (G64 Q) to it as one line (`naive_cam_chains`)."""

    lookahead_blocks: ClassVar[int]
    runs_arcs_whole: ClassVar[bool]
    blends_corners: ClassVar[bool]
    merges_naive_cam = False
    _of_kind: ClassVar[dict[str, Planner]] = {}

    @staticmethod
    def register(kind: str, planner: Planner) -> None:
        """Make `planner` the one a controller of this `[controller] kind` (`machine.CONTROLLERS`) runs."""
        Planner._of_kind[kind] = planner

    @staticmethod
    def of_kind(kind: str) -> Planner:
        """The planner a controller of this kind runs (`register`)."""
        if kind not in Planner._of_kind:
            raise ConfigError("controller.kind", kind, f"one of {', '.join(Planner._of_kind)}")
        return Planner._of_kind[kind]

    @abstractmethod
    def queue(self, tp: Toolpath, model: ControllerModel, feed_mm_s: np.ndarray | None,
              pauses: np.ndarray | None, modes: PathModes | None) -> Queue:
        """The blocks the planner runs for the toolpath at feed_mm_s (per move; None: programmed),
        stopping at the pauses (`pauses_s`), in the path modes `modes` (None: the controller's own)."""

    def timed(self, q: Queue, ve: np.ndarray, t: np.ndarray, model: ControllerModel
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per block the time (s) it runs in and whether it runs as a linear ramp, and the blend arcs
        (`Execution.blends`), given the planned junction speeds ve (mm/s, n+1) and the trapezoids'
        times t: the trapezoids as they are."""
        return t, np.zeros(len(t), bool), q.blends


@dataclass(frozen=True)
class ControllerModel:
    """Planner settings. Rates mm/s, accelerations mm/s², lengths mm, times s (grbl: $110-$112 in
    mm/min, $120-$122, $11 junction deviation, $12 arc tolerance; a buffer of 16 blocks on an AVR.
    LinuxCNC: [AXIS_*] MAX_VELOCITY/MAX_ACCELERATION, G64 P, ARC_BLEND_OPTIMIZATION_DEPTH 50).
    planner (keyword, required): the planner the controller runs (`GrblPlanner()`, `LinuxCNCPlanner()`);
    lookahead_blocks: how many blocks it plans ahead (None: the planner's own depth);
    naive_cam_mm: the naive-CAM tolerance before the program sets a path mode (LinuxCNC's startup
    G64 Q, or P without Q; 0 where the planner merges nothing, `Planner.merges_naive_cam`)."""

    max_rate_mm_s: tuple[float, float, float]
    accel_mm_s2: tuple[float, float, float]
    junction_deviation_mm: float = 0.01
    lookahead_blocks: int | None = None
    block_rate_hz: float = float("inf")
    arc_tolerance_mm: float = 0.002
    exact_stop: bool = False
    planner: Planner = field(kw_only=True)
    blend_tolerance_mm: float = 0.0
    naive_cam_mm: float = 0.0
    servo_period_s: float = 0.001
    tool_change_s: float = 0.0
    spindle_start_s: float = 0.0
    coolant_s: float = 0.0
    command_s: float = 0.0

    def __post_init__(self) -> None:
        for name in ("max_rate_mm_s", "accel_mm_s2"):
            v = np.asarray(getattr(self, name), float)
            if v.shape != (3,) or not (v > 0).all():
                raise ConfigError(name, getattr(self, name), "three positive numbers (X, Y, Z)")
        for name in ("junction_deviation_mm", "blend_tolerance_mm", "naive_cam_mm", "tool_change_s", "spindle_start_s",
                     "coolant_s", "command_s"):
            if not getattr(self, name) >= 0:
                raise ConfigError(name, getattr(self, name), "must be ≥ 0")
        if not isinstance(self.planner, Planner):
            raise ConfigError("planner", self.planner, "a planner: GrblPlanner() or LinuxCNCPlanner()")
        if self.lookahead_blocks is None:
            object.__setattr__(self, "lookahead_blocks", self.planner.lookahead_blocks)
        if self.lookahead_blocks < 1:
            raise ConfigError("lookahead_blocks", self.lookahead_blocks, "must be ≥ 1")
        if not self.block_rate_hz > 0:
            raise ConfigError("block_rate_hz", self.block_rate_hz, "must be > 0")
        if not self.arc_tolerance_mm > 0:
            raise ConfigError("arc_tolerance_mm", self.arc_tolerance_mm, "must be > 0")
        if not self.servo_period_s > 0:
            raise ConfigError("servo_period_s", self.servo_period_s, "must be > 0")
        if self.naive_cam_mm > 0 and not self.planner.merges_naive_cam:
            raise ConfigError("naive_cam_mm", self.naive_cam_mm, "0 for a controller that merges no straight feeds")

    @classmethod
    def from_machine(cls, machine) -> ControllerModel:
        """The model of a machine's controller: its axis rates and accelerations, the planner of its
        kind (`Planner.of_kind`) with that planner's look-ahead depth; a LinuxCNC controller's blend
        tolerance is its startup G64 P, which sets the naive-CAM tolerance too where the planner merges."""
        ax = [machine.axes[a] for a in "xyz"]
        c = machine.controller
        planner = Planner.of_kind(c.kind)
        return cls(max_rate_mm_s=tuple(a.vmax_mm_s for a in ax), accel_mm_s2=tuple(a.amax_mm_s2 for a in ax),
                   junction_deviation_mm=c.junction_deviation_mm, block_rate_hz=c.block_rate_Hz, planner=planner,
                   blend_tolerance_mm=c.blend_tolerance_mm, tool_change_s=c.tool_change_s,
                   naive_cam_mm=c.blend_tolerance_mm if planner.merges_naive_cam else 0.0,
                   spindle_start_s=c.spindle_start_s, coolant_s=c.coolant_s, command_s=c.command_s)
