"""What a real motion planner does with a program: cycle time and the speed actually reached.

The machine's `[controller] kind` picks the planner (`ControllerModel.from_machine`): grbl's
(`GrblPlanner`, module `grbl`: arcs as chords, junction deviation, 16-block look-ahead) for grbl, and
LinuxCNC 2.9's (`LinuxCNCPlanner`, module `linuxcnc`: arcs whole, blend arcs at corners, 50-segment
look-ahead) for every other kind, the model for look-ahead controllers that blend corners within a
tolerance (LinuxCNC, Mach3, Fanuc-like); only a `linuxcnc` controller merges naive-CAM feeds. The
modules, one job each:

- `model`: the settings (`ControllerModel`), the path modes (`PathModes`), what a planner is and
  queues (`Planner`, `Queue`);
- `grbl`, `linuxcnc`: the two planners (`GrblPlanner`, `LinuxCNCPlanner`), each registering the kinds it runs;
- `run`: `execute`, `execute_program`, `program_time`; `execution`: the result (`Execution`);
- `paths`: the path modes a program sets (G61, G61.1, G64 P Q), LinuxCNC's naive-CAM chains, `block_lengths`;
- `segments`, `blends`: LinuxCNC's segments and how it passes corners (`corner_speeds`, `blend_zones`;
  over a program's samples `zone_samples`, `programmed_arcs`);
- `pauses`: commands between moves, which stop the motion and take time;
- `profile`: the look-ahead passes and the trapezoidal profile.

Rates and feeds mm/s (a toolpath's programmed feed as `Toolpath.feed_mm_s`), accelerations mm/s²,
lengths mm, times s. A controller that processes at most `block_rate_hz` blocks per second cannot
finish a block of length L faster than 1/rate (speed ≤ L·rate). Times count from the first motion to
the end of the last one.
"""

from .blends import blend_zones, corner_speeds, programmed_arcs, zone_samples
from .execution import Execution
from .grbl import Blocks, GrblPlanner, to_blocks
from .linuxcnc import LinuxCNCPlanner
from .model import EXACT_PATH, EXACT_STOP, ControllerModel, PathModes, Planner, Queue
from .paths import block_lengths, naive_cam_chains, path_modes
from .pauses import PAUSE_KINDS, pauses_s
from .run import execute, execute_program, program_time

__all__ = ["EXACT_PATH", "EXACT_STOP", "PAUSE_KINDS", "Blocks", "ControllerModel", "Execution",
           "GrblPlanner", "LinuxCNCPlanner", "PathModes", "Planner", "Queue", "block_lengths", "blend_zones",
           "corner_speeds", "execute", "execute_program", "naive_cam_chains", "path_modes", "pauses_s",
           "program_time", "programmed_arcs", "to_blocks", "zone_samples"]
