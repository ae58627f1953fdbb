"""Cutting tools: geometry as a radial profile (`cutter`), and more modules beside it."""

from .cutter import Tool

__all__ = ["Tool"]
