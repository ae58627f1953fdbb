"""LinuxCNC 2.9's own trajectory planner as the oracle for cycle times: runs a program through the
headless harness in ../shared/tools/lcnc (the uspace simulator, Debian's linuxcnc-uspace) with a
machine's axis limits, and the controller model on the same program for comparison.

One LinuxCNC instance per machine: every run holds /tmp/lcnc.lock (fcntl), as the harness README asks.
The simulator's own command latencies (its io process changes tools and switches coolant in real
time, so at a speed-up they last longer in simulated time) are measured by the same harness on
two-move programs and given to the model in place of the machine's (`sim_latencies`).

Run as a script it prints one JSON object, per program: LinuxCNC's seconds and the model's:
    python tests/lcnc_harness.py MACHINE PROGRAM...
"""

from __future__ import annotations

import dataclasses
import fcntl
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from millpost.controller import ControllerModel, LinuxCNCPlanner, program_time
from millpost.gcode import ReaderOptions, read_program
from millpost.machine import Machine

ROOT = Path(__file__).resolve().parents[1]
HARNESS = ROOT.parent / "shared" / "tools" / "lcnc" / "lcnc_cycle_time.py"
PYTHON = Path("/usr/bin/python3")
LOCK = Path("/tmp/lcnc.lock")
SPEEDUP = 5.0
# two moves with a stop between them, and the same with a command in the stop
_PROBE = "G21 G90 G17\nG0 X0 Y0 Z0\nG0 X10\n{}\nG0 X20\nM2\n"
PROBES = {"stop": "G4 P0", "tool_change_s": "T2 M6", "coolant_s": "M8", "command_s": "S1000 M3"}


def missing() -> str | None:
    """Why the harness cannot run here (None when it can)."""
    if not HARNESS.exists():
        return f"{HARNESS} is absent"
    if not Path("/usr/bin/linuxcnc").exists():
        return "LinuxCNC (Debian linuxcnc-uspace) is not installed"
    if subprocess.run([str(PYTHON), "-c", "import linuxcnc"], capture_output=True).returncode:
        return "the system Python has no linuxcnc module"
    return None


def tool_lengths_mm() -> dict[int, float]:
    """Tool lengths (mm) of the harness's tool table: G43 H<n> moves the programmed Z by them."""
    out = {}
    for line in (HARNESS.parent / "sim_mm.tbl").read_text().splitlines():
        words = {w[0]: w[1:] for w in line.split(";")[0].split() if w}
        if "T" in words and "Z" in words:
            out[int(words["T"])] = float(words["Z"])
    return out


def limits(machine: Machine) -> list[str]:
    """The machine's axis rates (mm/s) and accelerations (mm/s²) as harness options."""
    ax = [machine.axes[a] for a in "xyz"]
    vel = ",".join(f"{a.name.upper()}={a.vmax_mm_min / 60.0:.6g}" for a in ax)
    acc = ",".join(f"{a.name.upper()}={a.amax_mm_s2:.6g}" for a in ax)
    return ["--max-vel", vel, "--max-acc", acc]


def _session(sid: int) -> dict[int, str]:
    """Processes of a session: pid -> command name."""
    out = {}
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                if os.getsid(int(entry)) == sid:
                    out[int(entry)] = Path(f"/proc/{entry}/comm").read_text().strip()
            except OSError:
                pass
    return out


def _children(pid: int) -> list[int]:
    out = []
    for entry in os.listdir("/proc"):
        if entry.isdigit():
            try:
                stat = Path(f"/proc/{entry}/stat").read_text()
            except OSError:
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                out.append(int(entry))
    return out


def _run_once(cmd: list[str], wall_s: float) -> dict:
    """One harness run. LinuxCNC's task process (milltask) sometimes dies mid-run and the harness then
    waits for its whole timeout: when it is gone, the run's display is ended (the harness cleans up)."""
    proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    t0, seen, missed = time.monotonic(), False, 0
    while proc.poll() is None and time.monotonic() - t0 < wall_s:
        time.sleep(1.0)
        session = {}
        for child in _children(proc.pid):  # LinuxCNC runs in its own session under the harness
            session.update(_session(child))
        alive = "milltask" in session.values()
        seen |= alive
        missed = 0 if alive else missed + 1
        if seen and missed >= 3 and proc.poll() is None:
            for pid, name in session.items():
                if name.startswith("headless_displ"):
                    os.kill(pid, signal.SIGTERM)
            seen = False
    if proc.poll() is None:
        proc.kill()
    out, err = proc.communicate()
    lines = out.strip().splitlines()
    return json.loads(lines[-1]) if lines else {"ok": False, "error": err[-2000:]}


def run(program: Path, machine: Machine, expected_s: float, *, speedup: float = SPEEDUP, attempts: int = 3) -> dict:
    """LinuxCNC's result for a program (the harness's JSON: `seconds`, `ok`, `errors`), holding the
    lock for each run; a run whose task process died is retried. A run is given 1.5 × the expected
    time plus a minute of simulated time."""
    LOCK.touch(exist_ok=True)
    budget = 1.5 * expected_s + 60.0
    cmd = [str(PYTHON), str(HARNESS), str(program), "--speedup", f"{speedup:g}", "--timeout", f"{budget:g}",
           *limits(machine)]
    res: dict = {}
    for _ in range(attempts):
        with open(LOCK) as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            res = _run_once(cmd, budget / speedup + 300)
        if res.get("ok") or res.get("errors"):
            break
    return res


def sim_latencies(machine: Machine, speedup: float = SPEEDUP) -> dict[str, float]:
    """The simulator's stand-still time (s) for a tool change, coolant and a spindle command,
    each against a plain stop, measured by the harness at this speed-up."""
    seconds = {}
    with tempfile.TemporaryDirectory() as d:
        for name, command in PROBES.items():
            path = Path(d) / f"{name}.ngc"
            path.write_text(_PROBE.format(command))
            res = run(path, machine, 5.0, speedup=speedup)
            if not res.get("ok"):
                raise RuntimeError(f"LinuxCNC probe {name} failed: {res.get('errors') or res.get('error')}")
            seconds[name] = float(res["seconds"])
    stop = seconds.pop("stop")
    out = {k: max(v - stop, 0.0) for k, v in seconds.items()}
    out["spindle_start_s"] = out["command_s"]
    return out


def model(machine: Machine, latencies: dict[str, float]) -> ControllerModel:
    """The machine's controller model as the simulated controller is configured: LinuxCNC's planner
    and canon (it merges naive-CAM feeds) with the machine's axes, no G64 P or Q, no block rate limit but the servo period's, and the
    simulator's command latencies."""
    return dataclasses.replace(ControllerModel.from_machine(machine), planner=LinuxCNCPlanner(merges_naive_cam=True),
                               lookahead_blocks=50, blend_tolerance_mm=0.0, naive_cam_mm=0.0,
                               block_rate_hz=float("inf"), **latencies)


def model_seconds(program: Path, controller: ControllerModel) -> float:
    """The model's time for the program, from the first motion to the last (what the harness counts),
    read in LinuxCNC's frame (homes at machine zero) with the harness's tool lengths."""
    options = ReaderOptions.linuxcnc()
    options.tool_lengths_mm = tool_lengths_mm()
    return program_time(read_program(program, options), controller)


def main(argv: list[str]) -> int:
    machine = Machine.load(argv[0])
    ctl = model(machine, sim_latencies(machine))
    rows = {}
    for name in argv[1:]:
        t_model = model_seconds(Path(name), ctl)
        res = run(Path(name), machine, t_model)
        rows[name] = {"linuxcnc_s": res.get("seconds"), "model_s": round(t_model, 3), "ok": res.get("ok"),
                      "errors": res.get("errors") or res.get("error")}
        if res.get("seconds"):
            rows[name]["ratio"] = round(t_model / res["seconds"], 4)
        print(json.dumps({name: rows[name]}), file=sys.stderr)
    print(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
