"""Spindle-load logging over Modbus (RTU on a serial line, TCP, or RTU frames over TCP) with pymodbus.

A `RegisterMap` (a data file: built-ins in ``millpost/data/vfd_maps/``, or the user's own TOML) says
which registers hold what; `SpindleLogger` reads them at a fixed rate and writes the log format
(`millpost.measure.log`): t_s the time of the read (the middle of request and response), due_s the
time its tick was due (their difference is the logger's latency). Every tick k is due at t₀ + k/rate.
A tick whose read fails (timeout, exception response, connection lost) or that the logger could not serve in time (overrun) is lost: a run
of lost ticks becomes one gap record [first lost tick, last lost tick] with its reason, counted in the
summary, and the logger reconnects at the next tick. Ctrl-C (KeyboardInterrupt) ends the log cleanly:
the file holds every row taken up to then.
"""

from __future__ import annotations

import math
import sys
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from ..config import Table, load_description
from ..errors import ConfigError, MillpostError
from .log import Gap, LogWriter, check_column_name

TABLES = ("holding", "input")
MAX_READ = 64       # registers per request (Modbus allows 125)
MAX_HOLE = 16       # read across unused registers up to this many to save a request


@dataclass(frozen=True)
class Register:
    """One value: log column, address, table, value = raw · scale + offset (raw two's complement if signed)."""

    column: str
    address: int
    table: str = "holding"
    scale: float = 1.0
    offset: float = 0.0
    signed: bool = False

    def decode(self, raw: int) -> float:
        if self.signed and raw >= 0x8000:
            raw -= 0x10000
        return raw * self.scale + self.offset


@dataclass(frozen=True)
class RegisterMap:
    """A drive's register map: name, description, source, Modbus device id and the registers to read."""

    name: str
    description: str
    source: str
    device_id: int
    registers: tuple[Register, ...]

    @classmethod
    def load(cls, name_or_path: str | Path) -> "RegisterMap":
        data, file = load_description("vfd_maps", name_or_path)
        t = Table(data, "", file)
        name, description, source = t.string("name"), t.string("description", ""), t.string("source", "")
        protocol = t.string("protocol", "modbus")
        if protocol != "modbus":
            refusal = t.string("refusal", "")
            raise ConfigError("protocol", protocol, f"not supported: {refusal}" if refusal else
                              "only standard Modbus (function codes 3 and 4) is supported", file=file)
        device_id = t.integer("device_id", 1, ge=0, le=247)
        regs = []
        raw = data.get("register", [])
        t._read.add("register")
        if not isinstance(raw, list) or not raw:
            raise ConfigError("register", raw, "needs at least one [[register]] table", file=file)
        for i, entry in enumerate(raw):
            r = Table(entry, f"register[{i}]", file)
            column = r.string("column")
            try:
                check_column_name(column)
            except MillpostError as exc:
                raise ConfigError(f"register[{i}].column", column, str(exc).split(": ", 1)[-1], file=file) from None
            regs.append(Register(column, r.integer("address", ge=0, le=0xFFFF), r.string("table", "holding",
                                                                                         choices=TABLES),
                                 r.number("scale", 1.0), r.number("offset", 0.0), bool(r.raw("signed", False))))
            r.done()
        t.done()
        columns = [g.column for g in regs]
        if len(set(columns)) != len(columns) or "t_s" in columns:
            raise ConfigError("register", columns, "each column once, and not t_s", file=file)
        return cls(name, description, source, device_id, tuple(regs))

    @property
    def columns(self) -> list[str]:
        return [r.column for r in self.registers]

    def requests(self) -> list[tuple[str, int, int, list[tuple[int, Register]]]]:
        """Contiguous reads: (table, start address, count, [(index in the response, register)])."""
        out: list[tuple[str, int, int, list[tuple[int, Register]]]] = []
        for table in TABLES:
            regs = sorted((r for r in self.registers if r.table == table), key=lambda r: r.address)
            group: list[Register] = []
            for r in regs:
                if group and (r.address - group[-1].address > MAX_HOLE or r.address - group[0].address >= MAX_READ):
                    out.append(_request(table, group))
                    group = []
                group.append(r)
            if group:
                out.append(_request(table, group))
        return out


def _request(table: str, group: list) -> tuple[str, int, int, list]:
    start = group[0].address
    return table, start, group[-1].address - start + 1, [(r.address - start, r) for r in group]


def make_client(target: str, *, timeout_s: float, baudrate: int = 9600, parity: str = "N", stopbits: int = 1):
    """A pymodbus client for `tcp:HOST[:PORT]` (Modbus TCP, port 502), `rtu-tcp:HOST:PORT` (RTU frames over
    TCP, as serial device servers speak) or `rtu:DEVICE` (RS-485 serial, e.g. rtu:/dev/ttyUSB0)."""
    from pymodbus import FramerType
    from pymodbus.client import ModbusSerialClient, ModbusTcpClient

    kind, _, rest = target.partition(":")
    if kind in ("tcp", "rtu-tcp") and rest:
        host, _, port = rest.rpartition(":") if rest.count(":") == 1 else (rest, "", "")
        host = host or rest
        framer = FramerType.SOCKET if kind == "tcp" else FramerType.RTU
        return ModbusTcpClient(host, port=int(port or 502), framer=framer, timeout=timeout_s, retries=0,
                               reconnect_delay=0, reconnect_delay_max=0)
    if kind == "rtu" and rest:
        return ModbusSerialClient(rest, framer=FramerType.RTU, baudrate=baudrate, parity=parity, stopbits=stopbits,
                                  bytesize=8, timeout=timeout_s, retries=0, reconnect_delay=0, reconnect_delay_max=0)
    raise MillpostError(f"unknown target {target!r}: give tcp:HOST[:PORT], rtu-tcp:HOST:PORT or rtu:DEVICE")


@dataclass
class LogSummary:
    """What a logging run did: rows written, ticks due, lost ticks and gaps by reason, duration (s)."""

    path: str
    rate_hz: float
    rows: int = 0
    ticks: int = 0
    gaps: int = 0
    lost_ticks: Counter = field(default_factory=Counter)
    reconnects: int = 0
    duration_s: float = 0.0
    interrupted: bool = False

    def as_dict(self) -> dict:
        return {"path": self.path, "rate_hz": self.rate_hz, "rows": self.rows, "ticks": self.ticks, "gaps": self.gaps,
                "lost_ticks": dict(self.lost_ticks), "reconnects": self.reconnects,
                "duration_s": round(self.duration_s, 3), "interrupted": self.interrupted}


class SpindleLogger:
    """Reads a register map at a fixed rate into a log file (see the module's docstring).

    client_factory: returns a fresh pymodbus client (called again after every failure, to reconnect).
    progress: called about twice a second with the summary and the last row (None: silent)."""

    def __init__(self, client_factory: Callable, regmap: RegisterMap, path: str | Path, *, rate_hz: float,
                 progress: Callable[[LogSummary, list[float]], None] | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not (0 < rate_hz <= 10000):
            raise MillpostError(f"rate must be in (0, 10000] Hz, got {rate_hz}")
        self.client_factory, self.map, self.path, self.rate = client_factory, regmap, Path(path), float(rate_hz)
        self.progress, self.clock = progress, clock
        self.requests = regmap.requests()

    def _read(self, client) -> list[float]:
        values = [math.nan] * len(self.map.registers)
        index = {r.column: i for i, r in enumerate(self.map.registers)}
        for table, start, count, regs in self.requests:
            fn = client.read_holding_registers if table == "holding" else client.read_input_registers
            rr = fn(start, count=count, device_id=self.map.device_id)
            if rr.isError():
                raise _Lost(f"exception response {getattr(rr, 'exception_code', '?')} at {table} {start:#06x}")
            if len(rr.registers) < count:
                raise _Lost(f"short response at {table} {start:#06x}: {len(rr.registers)} of {count} registers")
            for k, reg in regs:
                values[index[reg.column]] = reg.decode(rr.registers[k])
        return values

    def run(self, duration_s: float | None = None) -> LogSummary:
        """Log until duration_s (None: until Ctrl-C); the file is complete when this returns."""
        summary = LogSummary(str(self.path), self.rate)
        period = 1.0 / self.rate
        meta = {"source": f"millpost log, map {self.map.name}", "rate_hz": f"{self.rate:g}",
                "start_epoch_s": f"{time.time():.6f}"}
        lost_from, lost_reason = None, ""
        last_row: list[float] = []
        next_progress = 0.0
        with LogWriter(self.path, ["t_s", "due_s"] + self.map.columns, meta) as writer:
            client = None
            t0 = self.clock()

            def close_gap(last_lost_tick: int) -> None:
                nonlocal lost_from
                if lost_from is not None:
                    writer.gap(Gap(lost_from * period, last_lost_tick * period, lost_reason))
                    summary.gaps += 1
                    lost_from = None

            def lose(tick: int, n: int, reason: str) -> None:
                nonlocal lost_from, lost_reason
                if lost_from is not None and reason != lost_reason:
                    close_gap(tick - 1)
                if lost_from is None:
                    lost_from, lost_reason = tick, reason
                summary.lost_ticks[reason] += n

            k = 0
            try:
                client = self.client_factory()  # connect before the clock starts: tick 0 is not lost to it
                if not client.connect():
                    client.close()
                    client = None
                t0 = self.clock()
                while duration_s is None or k * period <= duration_s:
                    now = self.clock() - t0
                    due = k * period
                    if now < due:
                        time.sleep(due - now)
                    elif now - due >= period:  # late by a whole period or more: those ticks are lost
                        behind = int((now - due) / period)
                        if duration_s is not None:
                            behind = min(behind, int(duration_s / period) - k + 1)
                        lose(k, behind, "overrun")
                        k += behind
                        summary.ticks += behind
                        continue
                    summary.ticks += 1
                    try:
                        if client is None:
                            client = self.client_factory()
                            if not client.connect():
                                raise _Lost("no connection")
                            summary.reconnects += 1
                        t_req = self.clock()
                        values = self._read(client)
                        t_row = 0.5 * (t_req + self.clock()) - t0
                    except Exception as exc:  # noqa: BLE001 - every failure of a tick is a recorded loss
                        reason = str(exc) if isinstance(exc, _Lost) else f"{type(exc).__name__}: {exc}"
                        lose(k, 1, reason.replace("\n", " ")[:120])
                        if client is not None and not (isinstance(exc, _Lost) and "exception response" in str(exc)):
                            client.close()
                            client = None
                    else:
                        close_gap(k - 1)
                        writer.row([t_row, due] + values)
                        summary.rows += 1
                        last_row = values
                    k += 1
                    if now >= next_progress:  # about twice a second: to disk, and the progress line
                        writer.flush()
                        summary.duration_s = now
                        if self.progress:
                            self.progress(summary, last_row)
                        next_progress = now + 0.5
            except KeyboardInterrupt:
                summary.interrupted = True
            close_gap(k - 1)
            summary.duration_s = self.clock() - t0
            if client is not None:
                client.close()
        return summary


class _Lost(Exception):
    """A tick whose read did not give a complete sample."""


def progress_line(columns: list[str]) -> Callable[[LogSummary, list[float]], None]:
    """A one-line progress display on stderr: time, rows, gaps, the last values."""
    def show(s: LogSummary, row: list[float]) -> None:
        values = "  ".join(f"{c}={v:.4g}" for c, v in zip(columns, row))
        sys.stderr.write(f"\r{s.duration_s:7.1f} s  {s.rows} rows  {s.gaps} gaps  {values}\033[K")
        sys.stderr.flush()
    return show
