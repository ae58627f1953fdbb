"""`millpost log` against a pymodbus server on 127.0.0.1 started here (tests/vfd_server.py): 50 Hz for
10 s with the server killed and restarted mid-run and exception responses every 4 s. Every due sample is
a row or inside a recorded gap; every row equals a response the server recorded."""

from __future__ import annotations

import json
import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from millpost.errors import ConfigError
from millpost.measure import read_log
from millpost.measure.modbus import RegisterMap

HERE = Path(__file__).resolve().parents[1]  # tests/, where vfd_server.py lives
SRC = HERE.parent / "src"
RATE = 50.0


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_server(port: int, record: Path, framer: str = "socket") -> subprocess.Popen:
    proc = subprocess.Popen([sys.executable, str(HERE / "vfd_server.py"), str(port), str(record), framer],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 10
    while time.time() < deadline:
        with socket.socket() as s:
            if s.connect_ex(("127.0.0.1", port)) == 0:
                return proc
        time.sleep(0.05)
    proc.kill()
    raise RuntimeError("the test server did not start")


def wait_for_rows(folder: Path, timeout_s: float = 30.0) -> None:
    """Until the logger (a fresh interpreter: imports take seconds) has written its first row."""
    deadline = time.time() + timeout_s
    while time.time() < deadline:
        for f in folder.glob(".log.csv.*"):
            if any(line[:1].isdigit() for line in f.read_text().splitlines()):
                return
        time.sleep(0.05)
    raise RuntimeError("the logger wrote nothing")


def stop(*procs: subprocess.Popen) -> None:
    for p in procs:
        p.kill()
        p.wait(5)


def run_logger(args: list[str]) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(SRC))
    return subprocess.Popen([sys.executable, "-m", "millpost.cli", "log", *args], env=env, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def served(record: Path) -> tuple[np.ndarray, np.ndarray]:
    """(wall times, raw rows of 0x2103..0x210F) of the successful responses the server recorded."""
    times, rows = [], []
    for line in record.read_text().splitlines():
        parts = line.split()
        if len(parts) == 14:
            times.append(float(parts[0]))
            rows.append([int(v) for v in parts[1:]])
    return np.array(times), np.array(rows)


@pytest.mark.parametrize("framer", ["socket", "rtu"])
def test_logger_survives_a_vanishing_server(tmp_path, framer):
    port, record = free_port(), tmp_path / "served.txt"
    server = start_server(port, record, framer)
    out, summary_file = tmp_path / "log.csv", tmp_path / "summary.json"
    duration = 10.0 if framer == "socket" else 3.0
    target = f"{'tcp' if framer == 'socket' else 'rtu-tcp'}:127.0.0.1:{port}"
    logger = run_logger([target, "--map", "delta-ms300", "-o", str(out), "--rate", str(RATE),
                         "--duration", str(duration), "--json", str(summary_file)])
    try:
        wait_for_rows(tmp_path)
        if framer == "socket":
            time.sleep(3.0)
            server.send_signal(signal.SIGKILL)
            server.wait(5)
            time.sleep(2.0)
            server = start_server(port, record, framer)
        _, err = logger.communicate(timeout=60)
    finally:
        stop(logger, server)
    assert logger.returncode == 0, err
    log = read_log(out)
    summary = json.loads(summary_file.read_text())
    # every due tick is a row or inside a recorded gap, exactly once
    n_ticks = int(duration * RATE) + 1
    tick_of_row = np.round(log["due_s"] * RATE).astype(int)
    assert np.all(log.t_s >= log["due_s"] - 1e-6)                       # read at or after its tick
    k = np.arange(n_ticks)
    in_gap = np.zeros(n_ticks, int)
    for g in log.gaps:
        in_gap += (k / RATE >= g.t_start_s - 1e-6) & (k / RATE <= g.t_end_s + 1e-6)
    seen = np.bincount(tick_of_row, minlength=n_ticks) + in_gap
    assert np.all(seen == 1), np.flatnonzero(seen != 1)[:10]
    assert summary["rows"] == len(log) and summary["gaps"] == len(log.gaps)
    assert summary["rows"] + sum(summary["lost_ticks"].values()) == n_ticks
    if framer == "socket":
        outage = [g for g in log.gaps if g.t_end_s - g.t_start_s > 1.0]   # the server was away ~2 s of 10
        assert outage and summary["reconnects"] >= 1
        # rows on both sides of it: the logger came back (how many ticks a busy machine lets it serve is
        # not the test's business: those it misses are counted as overrun gaps, checked above)
        assert log["due_s"].min() < outage[0].t_start_s and log["due_s"].max() > outage[-1].t_end_s
    # values equal served ones (in raw register counts), in the order served (one response a request) ...
    wall, raw = served(record)
    epoch = float(log.meta["start_epoch_s"])
    scale = {"output_frequency_Hz": (0, 0.01), "spindle_current_A": (1, 0.01), "spindle_rpm": (9, 1),
             "spindle_power_W": (12, 1)}
    logged = np.column_stack([np.round(log[c] / s).astype(int) for c, (_, s) in scale.items()])
    served_rows = raw[:, [i for i, _ in scale.values()]]
    match, j = [], 0
    for t, row in zip(log.t_s, logged):
        hits = np.flatnonzero(np.all(served_rows[j:] == row, axis=1))
        assert hits.size, (t, row)
        j += int(hits[0])
        match.append(j)
        j += 1
    # ... and served when the row says: a row's time is the middle of its request and response, so the
    # server's clock lies within half the round trip of it, which is at most the row's latency after its
    # tick (t_s - due_s); up to one offset for the whole run (the logger's clock starts after its
    # connection, a little after the log's start epoch). A fixed window (0.1 s) failed on a busy machine.
    r = wall[match] - (epoch + log.t_s)
    slack = log.t_s - log["due_s"] + 2e-3                                 # + the printed precision
    assert np.max(r - slack) <= np.min(r + slack), (np.max(r - slack), np.min(r + slack))


def test_ctrl_c_ends_with_a_complete_file(tmp_path):
    port, record = free_port(), tmp_path / "served.txt"
    server = start_server(port, record)
    out = tmp_path / "log.csv"
    logger = run_logger([f"tcp:127.0.0.1:{port}", "--map", "delta-ms300", "-o", str(out), "--rate", "100"])
    try:
        wait_for_rows(tmp_path)
        time.sleep(1.0)
        logger.send_signal(signal.SIGINT)
        _, err = logger.communicate(timeout=20)
    finally:
        stop(logger, server)
    assert logger.returncode == 0, err
    assert "interrupted" in err
    log = read_log(out)  # complete: every row written before the interrupt reads back, in time order
    assert len(log) >= 1 and np.all(np.diff(log.t_s) > 0)  # (how many a busy machine lets it log varies)


def test_huanyang_is_refused_clearly():
    with pytest.raises(ConfigError, match="non-standard function codes"):
        RegisterMap.load("huanyang-hy")


def test_register_map_requests_group_contiguous_reads():
    m = RegisterMap.load("delta-ms300")
    reqs = m.requests()
    assert [(t, a, n) for t, a, n, _ in reqs] == [("holding", 0x2103, 13)]
