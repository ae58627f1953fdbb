"""Measurements: the log format and its reader/writer (`log`), alignment of a log to the program it
recorded (`alignment`), synthetic logs from the forward model (`synthetic`), VFD register maps and the
Modbus spindle logger (`vfd`, `modbus`)."""

from .alignment import Alignment, align
from .log import COLUMNS, Gap, Log, LogWriter, read_log, write_log

__all__ = ["COLUMNS", "Alignment", "Gap", "Log", "LogWriter", "align", "read_log", "write_log"]
