"""The job report: one self-contained HTML page (figures inline as SVG, no scripts, opens offline)
showing what optimize did, where on the part and why. matplotlib is imported only when a figure is
drawn."""

from .data import ReportData, collect, read_trace
from .page import headline, render, write_report

__all__ = ["ReportData", "collect", "headline", "read_trace", "render", "write_report"]
