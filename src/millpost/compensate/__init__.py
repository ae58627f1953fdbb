"""Offline deflection compensation: the program with each cutting point moved against the static
deflection the predicted force causes (tool beam and machine compliance), and the predicted surface
error along the finished walls and floors before and after.

    result = compensate(load_job("sample_jobs/thin_wall_finish"))
    result.text          # the program, only X/Y/Z words of cutting moves changed (and points added)
    result.summary       # surface error per operation before and after (µm), iterations, points
"""

from .deflection import deflection_vectors
from .model import Deflected, deflected_run
from .run import Compensation, compensate
from .surface import Surfaces

__all__ = ["Compensation", "Deflected", "Surfaces", "compensate", "deflected_run", "deflection_vectors"]
