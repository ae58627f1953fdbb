"""The controller model's settings (`ControllerModel`), built from a machine's controller."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConfigError

PLANNERS = ("grbl", "linuxcnc")


@dataclass(frozen=True)
class ControllerModel:
    """Planner settings. Rates mm/s, accelerations mm/s², lengths mm, times s (grbl: $110-$112 in
    mm/min, $120-$122, $11 junction deviation, $12 arc tolerance; a buffer of 16 blocks on an AVR.
    LinuxCNC: [AXIS_*] MAX_VELOCITY/MAX_ACCELERATION, G64 P, ARC_BLEND_OPTIMIZATION_DEPTH 50).
    merges_naive_cam: the controller merges consecutive straight feeds within the naive-CAM tolerance
    into one line (LinuxCNC's canon layer: `naive_cam_chains`; a program's G64 P/Q sets the tolerance);
    naive_cam_mm: that tolerance before the program sets a path mode (LinuxCNC's startup G64 Q, or P
    without Q; 0 where the controller merges nothing)."""

    max_rate_mm_s: tuple[float, float, float]
    accel_mm_s2: tuple[float, float, float]
    junction_deviation_mm: float = 0.01
    lookahead_blocks: int = 16
    block_rate_hz: float = float("inf")
    arc_tolerance_mm: float = 0.002
    exact_stop: bool = False
    planner: str = "grbl"
    blend_tolerance_mm: float = 0.0
    merges_naive_cam: bool = False
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
        if self.lookahead_blocks < 1:
            raise ConfigError("lookahead_blocks", self.lookahead_blocks, "must be ≥ 1")
        if not self.block_rate_hz > 0:
            raise ConfigError("block_rate_hz", self.block_rate_hz, "must be > 0")
        if not self.arc_tolerance_mm > 0:
            raise ConfigError("arc_tolerance_mm", self.arc_tolerance_mm, "must be > 0")
        if not self.servo_period_s > 0:
            raise ConfigError("servo_period_s", self.servo_period_s, "must be > 0")
        if self.planner not in PLANNERS:
            raise ConfigError("planner", self.planner, f"one of {', '.join(PLANNERS)}")
        if self.naive_cam_mm > 0 and not self.merges_naive_cam:
            raise ConfigError("naive_cam_mm", self.naive_cam_mm, "0 for a controller that merges no straight feeds")

    @classmethod
    def from_machine(cls, machine) -> "ControllerModel":
        """The model of a machine's controller: its axis rates and accelerations, its planner (a
        LinuxCNC controller's blend tolerance is its startup G64 P, which sets the naive-CAM tolerance
        too; only LinuxCNC merges naive-CAM feeds, `Controller.merges_naive_cam`)."""
        ax = [machine.axes[a] for a in "xyz"]
        c = machine.controller
        return cls(max_rate_mm_s=tuple(a.vmax_mm_min / 60.0 for a in ax), accel_mm_s2=tuple(a.amax_mm_s2 for a in ax),
                   junction_deviation_mm=c.junction_deviation_mm, block_rate_hz=c.block_rate_Hz,
                   planner=c.planner, lookahead_blocks=16 if c.planner == "grbl" else 50,
                   blend_tolerance_mm=c.blend_tolerance_mm, tool_change_s=c.tool_change_s,
                   merges_naive_cam=c.merges_naive_cam,
                   naive_cam_mm=c.blend_tolerance_mm if c.merges_naive_cam else 0.0,
                   spindle_start_s=c.spindle_start_s, coolant_s=c.coolant_s, command_s=c.command_s)
