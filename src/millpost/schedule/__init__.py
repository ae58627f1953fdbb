"""Feed schedule: limits as rows of one convex program (Verscheure SOCP) solved by Clarabel.

`solve_path(grid, blocks)` for one segment; `schedule_samples(samples, limits)` per contiguous
cutting segment of a resampled program (rapids are not scheduled).
"""

from millpost.schedule.constraints import (AxisAcceleration, AxisVelocity, Centripetal, CornerSpeed, CurrentSlew,
                                           FeedLimit, Junction, MinSpeed, MotorCurrent, PathJerk, SpeedLoad,
                                           path_blocks)
from millpost.schedule.problem import ConicProblem, SolverOptions, Status
from millpost.schedule.rows import LocalRows, PathGrid, SoftFloor, SpeedBounds, StepRows
from millpost.schedule.solve import ProgramSchedule, Schedule, ScheduleOptions, schedule_samples, solve_path

__all__ = [
    "AxisAcceleration", "AxisVelocity", "Centripetal", "ConicProblem", "CornerSpeed", "CurrentSlew",
    "FeedLimit", "Junction", "MinSpeed",
    "LocalRows", "MotorCurrent", "PathGrid", "PathJerk", "ProgramSchedule", "Schedule", "ScheduleOptions",
    "SoftFloor", "SolverOptions", "SpeedBounds", "SpeedLoad", "Status", "StepRows", "path_blocks",
    "schedule_samples", "solve_path",
]
