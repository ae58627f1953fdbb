"""Stock: the workpiece as a height field with sparse extra intervals (undercuts), and its builders."""

from .grid import DEFAULT_CELL_MM, Stock, box, choose_cell
from .mesh import from_python, from_shape, from_step, from_stl, from_triangles, load

__all__ = ["DEFAULT_CELL_MM", "Stock", "box", "choose_cell", "from_python", "from_shape", "from_step",
           "from_stl", "from_triangles", "load"]
