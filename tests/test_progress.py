"""Progress and messages: bars on a terminal (a pty) and none when piped or --quiet; the stages report
through the callback in order; every verb's help has an example that parses; flags that need
another are refused, not ignored."""

from __future__ import annotations

import os
import pty
import re
import subprocess
import sys
from pathlib import Path

from millpost.cli import build_parser, main
from millpost.job import load_job
from millpost.optimize import optimize

ROOT = Path(__file__).resolve().parents[1]
JOB = ROOT / "sample_jobs" / "slotting"
ENV = {**os.environ, "PYTHONPATH": str(ROOT / "src"), "COLUMNS": "120"}
CMD = [sys.executable, "-m", "millpost.cli", "optimize", str(JOB)]


def _on_pty(args: list[str]) -> str:
    """Run a command with stdin/stdout/stderr on a pseudo-terminal; all it wrote."""
    pid, fd = pty.fork()
    if pid == 0:  # the child: exec the command on the terminal
        os.execve(args[0], args, ENV)
    out = bytearray()
    while True:
        try:
            chunk = os.read(fd, 65536)
        except OSError:  # EIO: the child closed the terminal
            break
        if not chunk:
            break
        out += chunk
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0, out.decode(errors="replace")[-2000:]
    return out.decode(errors="replace")


def test_progress_on_a_terminal_only(tmp_path):
    shown = _on_pty(CMD + ["-o", str(tmp_path / "a.nc")])
    # every stage that can take a second, the kernels' first load or compile in this process included
    for stage in ("read program", "compile kernels", "engagement", "forces", "schedule", "emission", "replay"):
        assert stage in shown, stage
    assert "\x1b[" in shown and "100%" in shown
    assert re.search(r"millpost: solved: cycle time [\d.]+ s programmed → [\d.]+ s optimized", shown)
    piped = subprocess.run(CMD + ["-o", str(tmp_path / "b.nc")], env=ENV, capture_output=True, text=True, check=True)
    assert "engagement" not in piped.stderr and "\x1b[" not in piped.stderr
    # piped: no bars; the headline, then the explanation lines (indented: why, per-tool table)
    lines = piped.stderr.splitlines()
    assert lines[0].startswith("millpost: solved: cycle time") and all(x.startswith("  ") for x in lines[1:])
    quiet = _on_pty(CMD + ["-o", str(tmp_path / "c.nc"), "--quiet"])
    assert quiet.strip() == ""
    assert (tmp_path / "a.nc").read_text() == (tmp_path / "b.nc").read_text() == (tmp_path / "c.nc").read_text()


def test_stages_report_through_the_callback():
    calls = []
    optimize(load_job(JOB), progress=lambda stage, done, total: calls.append((stage, done, total)))
    order = list(dict.fromkeys(c[0] for c in calls))
    assert [s for s in order if s != "compile kernels"] == ["read program", "stock", "engagement", "forces",
                                                             "schedule", "emission", "replay"]
    for counted in ("engagement", "forces", "schedule", "emission", "replay"):  # fractions that only grow
        got = [c for c in calls if c[0] == counted]
        assert got[-1][1] == got[-1][2] > 0 and all(a[1] <= b[1] for a, b in zip(got, got[1:])), counted
    for stage in order:  # each stage ends finished
        last = [c for c in calls if c[0] == stage][-1]
        assert last[2] > 0 and last[1] >= last[2]


def test_every_verb_has_an_example_that_parses():
    parser = build_parser()
    verbs = parser._subparsers._group_actions[0].choices
    assert {"calc", "convert", "inspect", "optimize", "recommend", "report", "simulate"} <= set(verbs)
    for name, sub in verbs.items():
        text = sub.format_help()
        assert "example:" in text, name
        lines = [ln.split() for ln in text.split("example:")[1].strip().splitlines()]
        assert lines[-1][:2] == ["millpost", name]
        for words in lines:
            assert parser.parse_args(words[1:]).command == words[1]


def test_recommend_plot_needs_sweep(capsys, tmp_path):
    code = main(["recommend", "--diameter", "6", "--flutes", "3", "--material", "al6061", "--machine",
                 "vmc-small", "--plot", str(tmp_path / "p.png")])
    assert code == 2 and "--sweep" in capsys.readouterr().err
    assert not (tmp_path / "p.png").exists()


def test_kernel_compiles_report_to_the_enclosing_callback_only():
    """`compiling` reports a stage while a numba dispatcher has no compiled copy in this process, to the
    callback of the enclosing `reporting` block; nothing outside it, nothing in a forked worker."""
    from types import SimpleNamespace

    from millpost._kernels import compiling
    from millpost.progress import current, reporting, silent

    fresh, ready = SimpleNamespace(signatures=[]), SimpleNamespace(signatures=["(float64,)"])
    calls = []
    with compiling(fresh):  # no callback set: silent
        pass
    with reporting(lambda *c: calls.append(c)):
        with compiling(ready):
            pass
        assert calls == []
        with compiling(ready, fresh):
            calls.append("call")
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # a forked worker: its reports would draw on the parent's terminal
            os.write(w, b"1" if current() is silent else b"0")
            os._exit(0)
        os.waitpid(pid, 0)
        assert os.read(r, 1) == b"1"
    assert calls == [("compile kernels", 0.0, 0.0), "call", ("compile kernels", 1.0, 1.0)]
    assert current() is silent
