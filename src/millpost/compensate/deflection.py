"""The static deflection vector of the tool under the mean cutting force, per path sample.

    δ = C_tool(a_p) · F_xy + C_machine · F            (mm; F the force ON the tool, N, machine XYZ)

C_tool: the cutter as a two-segment cantilever loaded at mid-depth of cut (`ToolBeam`), lateral only
(the shank is stiff along its axis); C_machine: the machine's compliance between tool and table
(`Machine.compliance_matrix`: per-axis 1/k, or a full symmetric 3×3 matrix such as a robot's). Both in
series; the tool is displaced along the force acting on it (a linear spring, as in the offline
correction of robot machining: Carriere et al., Int J Adv Manuf Technol 110, 2020).
"""

from __future__ import annotations

import numpy as np

from ..job import Job
from ..signals import Signals


def deflection_vectors(job: Job, signals: Signals) -> np.ndarray:
    """(N, 3) deflection of the tool at the load point (mm, machine XYZ) per sample: the machine's
    (`Signals.machine_deflection_mm`) plus the tool beam's lateral deflection (`Signals.tool_deflection_mm`, its
    magnitude) along the in-plane force."""
    force = np.asarray(signals.force_tool_N, float)
    delta = np.array(signals.machine_deflection_mm, float)
    f_xy = np.hypot(force[:, 0], force[:, 1])
    along = np.divide(force[:, :2], f_xy[:, None], out=np.zeros((len(force), 2)), where=f_xy[:, None] > 0)
    delta[:, :2] += signals.tool_deflection_mm[:, None] * along
    return delta
