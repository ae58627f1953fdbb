"""Safety gates (`millpost.safety`) and robust writing (`millpost.files`), through the CLI as a user
meets them: exit codes, messages naming file:line, no clobbered input, no partial output, modes kept.

Cases from the issue: a rapid into the stock before the first feed move; a misplaced stock box and
an open STL (nothing cut, every feed would be raised); a plunge far below the stock bottom; a cut
deeper than the flutes; outputs naming an input; a missing output folder; files written 0600;
an empty program; ds_mm = 0 and other absurd job values; invalid JSON; Ctrl-C."""

from __future__ import annotations

import json
import os
import signal
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import trimesh

from conftest import shared_data
from millpost import safety
from millpost.cli import main
from millpost.errors import MillpostError
from millpost.files import atomic_path, json_text, write_atomic

ROOT = Path(__file__).resolve().parents[1]
SLOT = "G21 G90\nG0 X-5 Y10 Z5\nS10000 M3\nG1 Z-2 F300\nG1 X25 F600\nG0 Z5\nM30\n"


def simulate(tmp_path, text: str, *extra: str, box: str = "0,0,-10,20,20,0", name: str = "p.nc") -> int:
    nc = tmp_path / name
    nc.write_text(text)
    return main(["simulate", str(nc), "--stock-box", box, "--cell", "0.1", "--tool-diameter", "6",
                 "--trace", str(tmp_path / "t.csv"), *extra])


def strict_json(text: str):
    def bad(token):
        raise AssertionError(f"invalid JSON constant {token}")
    return json.loads(text, parse_constant=bad)


# --- rapids -------------------------------------------------------------------------------------
def test_rapid_into_stock_before_the_first_feed_move_is_refused(tmp_path, capsys):
    rc = simulate(tmp_path, "G21 G90\nG0 X10 Y10 Z5\nG0 Z-2\nG0 Z5\nS10000 M3\nG1 X-5 F300\nM30\n")
    err = capsys.readouterr().err
    assert rc == 2 and f"{tmp_path / 'p.nc'}:3: rapid move runs into the stock" in err
    assert "Traceback" not in err and not (tmp_path / "t.csv").exists()


def test_a_crash_in_an_inch_program_is_said_in_inch(tmp_path, capsys):
    """The point where the rapid first meets material, in the program's own units (X0.3937, not X10.000:
    millimetres read as inches)."""
    rc = simulate(tmp_path, "G20 G90\nG0 X0.3937 Y0.3937 Z0.2\nG0 Z-0.0787\nG0 Z0.2\nS10000 M3\nG1 X-0.2 F12\nM30\n")
    err = capsys.readouterr().err
    assert rc == 2 and "rapid move runs into the stock at X0.3937 Y0.3937 Z-0.0" in err and "(in, a crash" in err


def test_first_move_ending_in_material_is_refused(tmp_path, capsys):
    assert simulate(tmp_path, "G21 G90\nG0 X10 Y10 Z-2\nG0 Z5\nS10000 M3\nG1 X-5 F300\nM30\n") == 2
    assert f"{tmp_path / 'p.nc'}:2: rapid move runs into the stock" in capsys.readouterr().err


def test_rapid_crash_cannot_be_allowed(tmp_path, capsys):
    with pytest.raises(SystemExit):  # argparse: not a gate one may override
        simulate(tmp_path, "G0 X10 Y10 Z-2\n", "--allow", "rapid")
    assert "invalid choice: 'rapid'" in capsys.readouterr().err


def test_axes_not_yet_named_are_not_checked(tmp_path):
    """Stock from Z0 to Z20: `G0 X10 Y10` leaves Z where the machine stands (the reader assumes 0,
    inside this stock); only once Z is named is the position known."""
    text = "G21 G90\nG0 X10 Y10\nG0 Z25\nS10000 M3\nG1 Z18 F300\nG1 X-5 F600\nG0 Z25\nM30\n"
    assert simulate(tmp_path, text, box="0,0,0,20,20,20") == 0


# --- no-cut ------------------------------------------------------------------------------------
def test_misplaced_box_is_refused_and_can_be_allowed(tmp_path, capsys):
    assert simulate(tmp_path, SLOT, box="100,100,-10,120,120,0") == 2
    err = capsys.readouterr().err
    assert "no feed move reaches the stock" in err and "--allow no-cut" in err
    assert not (tmp_path / "t.csv").exists()
    assert simulate(tmp_path, SLOT, "--allow", "no-cut", "--json", box="100,100,-10,120,120,0") == 0
    out = strict_json(capsys.readouterr().out)
    assert any(n.startswith("warning (no-cut, allowed)") for n in out["notes"])


def test_open_stl_is_refused(tmp_path, capsys):
    m = trimesh.creation.box(extents=(20, 20, 10))
    m.apply_translation((10, 10, -5))
    m.update_faces(m.face_normals[:, 2] < 0.5)  # the top face is missing
    m.remove_unreferenced_vertices()
    stl = tmp_path / "open.stl"
    m.export(stl)
    nc = tmp_path / "slot.nc"
    nc.write_text(SLOT)
    rc = main(["simulate", str(nc), "--stock", str(stl), "--tool-diameter", "6", "--trace", str(tmp_path / "t.csv")])
    assert rc == 2 and "no material at all" in capsys.readouterr().err


def test_feed_through_empty_stock_bounds_is_refused(tmp_path):
    """A stock whose bounds the feed moves cross but which holds nothing there (a hollow solid)."""
    from millpost import stock
    from millpost.engagement import engage
    from millpost.gcode import read_text
    from millpost.tools import Tool

    s = stock.box((0, 0, -10), (20, 20, 0), 0.1)
    s.top[:, 20:180] = s.z_floor  # nothing between X2 and X18 (a pocket already cleared)
    program = read_text("G21 G90\nG0 X10 Y-5 Z5\nS9000 M3\nG1 Z-2 F300\nG1 Y25 F600\nG0 Z5\nM2\n", "hollow.nc")
    with pytest.raises(MillpostError, match=r"hollow.nc:5: the feed moves pass through the stock's bounds"):
        engage(program, s, Tool(6.0), 0.2, (), stage="simulate")


# --- depth ------------------------------------------------------------------------------------
def test_plunge_far_below_the_stock_bottom_is_refused(tmp_path, capsys):
    text = "G21 G90\nG0 X10 Y10 Z5\nS10000 M3\nG1 Z-60 F100\nG0 Z5\nM30\n"
    assert simulate(tmp_path, text, "--flute-length", "80") == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'p.nc'}:4: the tool tip goes 50.000 mm below the stock bottom" in err
    assert "--allow below-stock" in err


def test_through_cut_into_the_spoilboard_is_a_note(tmp_path, capsys):
    text = "G21 G90\nG0 X-5 Y10 Z5\nS10000 M3\nG1 Z-10.5 F300\nG1 X25 F600\nG0 Z5\nM30\n"
    assert simulate(tmp_path, text, "--flute-length", "12") == 0
    assert "0.500 mm below the stock bottom" in capsys.readouterr().err


def test_cut_deeper_than_the_flutes_is_refused_stepdowns_are_not(tmp_path, capsys):
    one_pass = "G21 G90\nG0 X-5 Y10 Z5\nS10000 M3\nG1 Z-8 F300\nG1 X25 F600\nG0 Z5\nM30\n"
    assert simulate(tmp_path, one_pass, "--flute-length", "5") == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'p.nc'}:5: the tool meets material 8.000 mm deep, deeper than its flute length 5 mm" in err
    two_passes = ("G21 G90\nG0 X-5 Y10 Z5\nS10000 M3\nG1 Z-4 F300\nG1 X25 F600\nG0 Z5\nG0 X-5\n"
                  "G1 Z-8 F300\nG1 X25 F600\nG0 Z5\nM30\n")
    assert simulate(tmp_path, two_passes, "--flute-length", "5") == 0


# --- size ---------------------------------------------------------------------------------------
def test_sample_ceiling_is_an_upfront_estimate(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(safety, "MAX_SAMPLES", 100)
    assert simulate(tmp_path, SLOT, "--step", "0.1") == 2
    err = capsys.readouterr().err
    # rapid from the assumed start (0, 0, 0) to (-5, 10, 5): 12.25 mm, 123 samples; plunge 7 mm (70),
    # slot 30 mm (300), retract 7 mm (70), plus the start point: 564
    assert "564 path samples at ds_mm = 0.1 would need about" in err and "--allow large" in err
    assert simulate(tmp_path, SLOT, "--step", "0.1", "--allow", "large") == 0


def test_estimate_matches_resampling():
    from millpost.gcode import read_program

    program = read_program(ROOT / "sample_jobs" / "adaptive_pocket" / "program.nc")
    for ds in (0.05, 0.3, 1.7):
        assert safety.estimate_samples(program, ds) == len(program.toolpath.resample(ds))


# --- outputs ------------------------------------------------------------------------------------
def job_copy(tmp_path, name="slotting") -> Path:
    dst = tmp_path / name
    dst.mkdir()
    for f in (ROOT / "sample_jobs" / name).iterdir():
        (dst / f.name).write_bytes(f.read_bytes())
    return dst


@pytest.mark.parametrize("flag,target", [("-o", "program.nc"), ("--json", "job.toml"), ("--trace", "program.nc"),
                                         ("-o", "link.nc")])
def test_optimize_never_replaces_an_input(flag, target, tmp_path, capsys, monkeypatch):
    job = job_copy(tmp_path)
    os.link(job / "program.nc", job / "link.nc")  # a hard link is the same file
    before = {p.name: p.read_bytes() for p in job.iterdir()}
    monkeypatch.setattr("millpost.commands.optimize.optimize", lambda *a, **k: pytest.fail("work started"))
    assert main(["optimize", str(job), flag, str(job / target)]) == 2
    err = capsys.readouterr().err
    assert f"{job / target} is the same file as the input" in err and "Traceback" not in err
    assert {p.name: p.read_bytes() for p in job.iterdir()} == before


def test_job_output_naming_the_program_is_refused(tmp_path, capsys):
    job = job_copy(tmp_path)
    (job / "job.toml").write_text('output = "program.nc"\n' + (job / "job.toml").read_text())
    text = (job / "program.nc").read_text()
    assert main(["optimize", str(job)]) == 2
    assert "output" in capsys.readouterr().err
    assert (job / "program.nc").read_text() == text


def test_two_outputs_to_one_file_are_refused(tmp_path, capsys):
    job = job_copy(tmp_path)
    assert main(["optimize", str(job), "-o", str(tmp_path / "a.nc"), "--trace", str(tmp_path / "a.nc")]) == 2
    assert "the same file as the output" in capsys.readouterr().err


def test_convert_and_simulate_never_replace_their_input(tmp_path, capsys):
    nc = tmp_path / "p.nc"
    nc.write_text(SLOT)
    assert main(["convert", str(nc), "--to", "grbl", "-o", str(nc)]) == 2
    assert main(["simulate", str(nc), "--stock-box", "0,0,-10,20,20,0", "--tool-diameter", "6",
                 "--trace", str(nc)]) == 2
    assert "is the same file as the input" in capsys.readouterr().err
    assert nc.read_text() == SLOT


def test_missing_output_folder_is_found_before_the_work(tmp_path, capsys, monkeypatch):
    job = job_copy(tmp_path)
    monkeypatch.setattr("millpost.commands.optimize.optimize", lambda *a, **k: pytest.fail("work started"))
    out = tmp_path / "no" / "such" / "out.nc"
    assert main(["optimize", str(job), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert f"output {out}: the folder {out.parent} does not exist" in err and "millpost-tmp" not in err


def test_modes_are_kept_and_new_files_follow_the_umask(tmp_path):
    old = tmp_path / "old.nc"
    old.write_text("x")
    os.chmod(old, 0o640)
    write_atomic(old, "y")
    assert stat.S_IMODE(old.stat().st_mode) == 0o640 and old.read_text() == "y"
    mask = os.umask(0o027)
    try:
        new = tmp_path / "new.nc"
        write_atomic(new, "z")
        assert stat.S_IMODE(new.stat().st_mode) == 0o640
        os.umask(0o022)
        nc = tmp_path / "p.nc"
        nc.write_text(SLOT)
        assert main(["convert", str(nc), "--to", "linuxcnc", "-o", str(tmp_path / "c.ngc")]) == 0
        assert stat.S_IMODE((tmp_path / "c.ngc").stat().st_mode) == 0o644
    finally:
        os.umask(mask)


def test_interrupted_write_leaves_nothing(tmp_path):
    target = tmp_path / "out.nc"
    target.write_text("old")
    with pytest.raises(KeyboardInterrupt):
        with atomic_path(target) as tmp, open(tmp, "w") as fh:
            fh.write("half")
            raise KeyboardInterrupt
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["out.nc"]


def test_abrupt_exit_removes_the_temporary_file(tmp_path):
    """What the command's Ctrl-C handler does before it ends the process (os._exit, no unwinding): the
    temporary file of an output being written is removed and the old file stays as it was."""
    from millpost.files import PENDING, atomic_path, remove_pending

    target = tmp_path / "out.nc"
    target.write_text("old")
    with pytest.raises(OSError):  # the block cannot finish the file it lost (the process would be gone)
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            assert str(tmp) in PENDING
            remove_pending()
            assert not tmp.exists()
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["out.nc"]
    assert not PENDING


def _cpu_s(pid: int) -> float:
    """The CPU time (user + system, s) a process has spent, all its threads."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def test_ctrl_c_prints_interrupted_and_exits_130(tmp_path):
    """A real SIGINT in the middle of `optimize`: exit 130, one line, no traceback, no output file."""
    job = job_copy(tmp_path, "adaptive_pocket")
    # a fine sampling step, so that the run (2.5 s at the sample's step) is still busy after 4 s
    with open(job / "job.toml", "a") as fh:
        fh.write("\n[limits]\nds_mm = 0.005\n")
    out = tmp_path / "out.nc"
    env = dict(os.environ, PYTHONPATH=str(ROOT / "src"))
    proc = subprocess.Popen([sys.executable, "-m", "millpost.cli", "optimize", str(job), "-o", str(out)],
                            stderr=subprocess.PIPE, text=True, env=env)
    # interrupted once the run has spent 3 s of CPU (its imports up to the handler `run` installs take
    # ~0.2 s): a fixed wall-clock wait (4 s) can end, on a busy machine, before the process gets that far
    deadline = time.monotonic() + 300
    while proc.poll() is None and _cpu_s(proc.pid) < 3.0 and time.monotonic() < deadline:
        time.sleep(0.05)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == 130, err
    assert "millpost: interrupted" in err and "Traceback" not in err
    assert not out.exists() and not list(tmp_path.glob(".*millpost-tmp"))


# --- programs and job values --------------------------------------------------------------------
def test_empty_program_is_a_clear_error(tmp_path, capsys):
    job = job_copy(tmp_path)
    (job / "program.nc").write_text("%\n(nothing here)\n%\n")
    assert main(["optimize", str(job), "-o", str(tmp_path / "o.nc")]) == 2
    err = capsys.readouterr().err
    assert f"{job / 'program.nc'}: the program has no moves" in err and "Traceback" not in err
    assert main(["inspect", str(job / "program.nc")]) == 0
    assert strict_json(capsys.readouterr().out)["bbox_mm"] is None


def test_rapids_only_allowed_is_written_unchanged(tmp_path, capsys):
    """A program of rapids only (no feed move): refused by the no-cut gate; allowed, it is written as
    it came (no F word to change), with a warning, not a traceback."""
    job = job_copy(tmp_path)
    text = "G21 G90\nG0 Z5\nG0 X10 Y10\nG0 Z1\nG0 Z5\nM30\n"
    (job / "program.nc").write_text(text)
    out = tmp_path / "o.nc"
    assert main(["optimize", str(job), "-o", str(out)]) == 2
    assert "no feed moves" in capsys.readouterr().err and not out.exists()
    assert main(["optimize", str(job), "-o", str(out), "--allow", "no-cut"]) == 0
    assert "Traceback" not in capsys.readouterr().err
    assert out.read_text() == text


@pytest.mark.parametrize("table,key,value", [
    ("[limits]\nds_mm = 0", "limits.ds_mm", "0"), ("[limits]\nds_mm = -0.1", "limits.ds_mm", "-0.1"),
    ("[limits]\nds_mm = nan", "limits.ds_mm", "nan"), ("[limits]\nfeed_max_mm_min = inf", "limits.feed_max_mm_min", "inf"),
    ("[limits]\ndeflection_mm = 1e9", "limits.deflection_mm", "1000000000.0"),
    ("[limits]\ntool_safety_factor = 0.5", "limits.tool_safety_factor", "0.5"),
    ("[limits]\nfeed_max_mm_min = true", "limits.feed_max_mm_min", "True"),
    ("[safety]\nallow = [\"rapid\"]", "safety.allow", "'rapid'")])
def test_absurd_job_values_name_the_file_and_key(table, key, value, tmp_path, capsys):
    job = job_copy(tmp_path)
    text = (job / "job.toml").read_text()
    (job / "job.toml").write_text(text + "\n" + table + "\n")
    assert main(["optimize", str(job)]) == 2
    err = capsys.readouterr().err
    assert f"{job / 'job.toml'}: {key} = {value}:" in err and "Traceback" not in err


@pytest.mark.parametrize("box", ["[[0, 0, -10], [60, 40, nan]]", "[[0, 0, -1e300], [60, 40, 0]]"])
def test_absurd_stock_box_is_refused(box, tmp_path, capsys):
    job = job_copy(tmp_path)
    text = (job / "job.toml").read_text().replace("box = [[0, 0, -10], [60, 40, 0]]", f"box = {box}")
    (job / "job.toml").write_text(text)
    assert main(["optimize", str(job)]) == 2
    assert f"{job / 'job.toml'}: stock.box" in capsys.readouterr().err


def test_json_refuses_non_finite_numbers():
    with pytest.raises(MillpostError, match=r"summary: limits.power is not a finite number"):
        json_text({"limits": {"power": float("nan")}})
    assert strict_json(json_text({"a": [1.0, None]})) == {"a": [1.0, None]}


def test_optimize_summary_is_strict_json_and_job_allow_is_read(tmp_path, capsys):
    job = job_copy(tmp_path)
    (job / "job.toml").write_text((job / "job.toml").read_text() + '\n[safety]\nallow = ["below-stock"]\n')
    assert main(["optimize", str(job), "-o", str(tmp_path / "o.nc"), "--json", "-"]) == 0
    summary = strict_json(capsys.readouterr().out)
    assert np.isfinite(summary["cycle_time_after_s"]) and summary["status"] == "solved"


# --- real programs ------------------------------------------------------------------------------
LEDFLOOR_JOB = """program = "{program}"
material = "plywood"
machine = "hobby-router"
[stock]
box = {box}
cell_mm = 0.05
[tools.1]
diameter_mm = 1.4
flutes = 2
flute_length_mm = 6
stickout_mm = 12
"""


@pytest.mark.parametrize("box,rc", [("[[-10, -10, -6], [30, 30, 0]]", 0), ("[[100, 100, -6], [140, 140, 0]]", 2),
                                    ("[[-10, -10, -16], [30, 30, -10]]", 2)])
def test_fusion_ledfloor_box_must_be_where_the_program_cuts(box, rc, tmp_path, capsys):
    """Fusion's 2D contour of a 20 mm block in 6 mm plywood (cut to Z-3): with the sheet under the
    work zero it optimizes; the same sheet 100 mm away, or 10 mm too low, is refused (nothing cut)."""
    program = shared_data("fusion-ledfloor", "1024_block_14bit.nc")
    (tmp_path / "job.toml").write_text(LEDFLOOR_JOB.format(program=program, box=box))
    out = tmp_path / "out.nc"
    assert main(["optimize", str(tmp_path), "-o", str(out), "--json", "-"]) == rc
    captured = capsys.readouterr()
    if rc == 0:
        assert strict_json(captured.out)["removed_volume_mm3"] > 0 and out.exists()
    else:
        assert "no feed move reaches the stock" in captured.err and not out.exists()


def test_optimize_never_reports_a_nan_cycle_time(tmp_path, capsys, monkeypatch):
    """Whatever goes wrong upstream, a NaN cycle time is refused before anything is written."""
    from millpost.optimize import Result

    job = job_copy(tmp_path)
    summary = {"status": "solved", "cycle_time_before_s": 10.0, "cycle_time_after_s": float("nan"),
               "cycle_time_baseline_s": 9.0, "notes": []}
    monkeypatch.setattr("millpost.commands.optimize.optimize", lambda *a, **k: Result("G0 X0\n", summary, None))
    out = tmp_path / "o.nc"
    assert main(["optimize", str(job), "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "cycle_time_after_s is not a finite number" in err and "nan s" not in err and not out.exists()


def test_infinite_coordinate_never_reaches_a_report(tmp_path, capsys):
    """`X` followed by 309 nines reads as inf: simulate refuses naming the line, inspect refuses to
    print invalid JSON (unless the reader already refuses the word)."""
    text = "G21 G90\nG0 X0 Y0 Z5\nS9000 M3\nG1 X" + "9" * 309 + " F100\nM30\n"
    assert simulate(tmp_path, text) == 2
    err = capsys.readouterr().err
    assert f"{tmp_path / 'p.nc'}:4:" in err and "Traceback" not in err
    rc = main(["inspect", str(tmp_path / "p.nc")])
    captured = capsys.readouterr()
    assert rc == 2 and "Infinity" not in captured.out
    assert (f"{tmp_path / 'p.nc'}: summary: feed_length_mm is not a finite number" in captured.err
            or f"{tmp_path / 'p.nc'}:4:" in captured.err)


def test_batch_and_report_never_replace_an_input(tmp_path, capsys):
    from millpost.batch import run_one

    job = job_copy(tmp_path)
    (job / "job.toml").write_text('output = "program.nc"\n' + (job / "job.toml").read_text())
    text = (job / "program.nc").read_text()
    row = run_one(str(job), str(job))  # the output folder is the job's own
    assert row["status"] == "error" and "is the same file as the input" in row["message"]
    assert (job / "program.nc").read_text() == text
    trace = tmp_path / "t.csv"
    trace.write_text("s_mm\n0\n")
    assert main(["report", str(trace), "-o", str(trace)]) == 2
    assert "is the same file as the input" in capsys.readouterr().err and trace.read_text() == "s_mm\n0\n"


@pytest.mark.parametrize("line,message", [("tools = 5", "tools = 5: must be a table"),
                                          ("limits = 5", "limits = 5: must be a table"),
                                          ("dialect = 5", "dialect = 5: one of"),
                                          ('material = "nosuch"', "material = 'nosuch': unknown material")])
def test_wrong_types_in_the_job_name_the_file_and_key(line, message, tmp_path, capsys):
    job = job_copy(tmp_path)
    key = line.split()[0]
    kept = []
    for ln in (job / "job.toml").read_text().splitlines():
        if ln.startswith(f"[{key}"):
            break  # the job's own table of that name goes (and whatever follows it)
        if not ln.startswith(key + " "):
            kept.append(ln)
    (job / "job.toml").write_text(line + "\n" + "\n".join(kept) + "\n")
    assert main(["optimize", str(job)]) == 2
    err = capsys.readouterr().err
    assert f"{job / 'job.toml'}: {message}" in err and "Traceback" not in err


def test_fusion_through_cut_deeper_than_assumed_flutes_is_refused(tmp_path, capsys):
    """Fusion's adaptive + contour in 12.55 mm plywood with a 2.65 mm bit: without a flute length
    (3·D = 7.95 mm assumed) the 12.55 mm contour walls are refused, naming the line and the fix."""
    from millpost.gcode import read_program

    path = shared_data("fusion-ledfloor", "1055_utab_265bit.nc")
    bb = read_program(path).toolpath.bbox()
    box = f"{bb[0, 0] - 1},{bb[0, 1] - 1},-12.55,{bb[1, 0] + 1},{bb[1, 1] + 1},0"
    rc = main(["simulate", str(path), f"--stock-box={box}", "--cell", "0.1", "--step", "0.25", "--tool-diameter",
               "2.65", "--trace", str(tmp_path / "t.csv")])
    err = capsys.readouterr().err
    assert rc == 2 and not (tmp_path / "t.csv").exists()
    assert f"{path}:" in err and "deeper than its flute length 7.95 mm (3·D assumed: give flute_length_mm)" in err


# --- programs without a T word or without M3 ----------------------------------------------------
TOOL = "diameter_mm = 6\nflutes = 2\nflute_length_mm = 15\nstickout_mm = 25\n"
NO_T = "G21 G90\nG0 X-5 Y10 Z5\nS10000 M3\nG1 Z-2 F300\nG1 X25 F600\nG0 Z5\nM30\n"


def small_job(tmp_path, program: str, tools=(1,), extra: str = "", name="job") -> Path:
    d = tmp_path / name
    d.mkdir()
    (d / "p.nc").write_text(program)
    (d / "job.toml").write_text(f'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n{extra}\n'
                                '[stock]\nbox = [[0, 0, -10], [20, 20, 0]]\ncell_mm = 0.1\n'
                                + "".join(f"[tools.{n}]\n{TOOL}" for n in tools))
    return d


def optimized(d: Path, *extra: str) -> tuple[int, dict, str]:
    rc = main(["optimize", str(d), "-o", str(d / "out.nc"), "--json", str(d / "s.json"), *extra])
    out = (d / "out.nc").read_text() if rc == 0 else ""
    return rc, (strict_json((d / "s.json").read_text()) if rc == 0 else {}), out


def f_words(text: str) -> list[str]:
    import re
    return re.findall(r"F[\d.]+", text)


@pytest.mark.parametrize("number", [0, 4])
def test_a_program_without_t_words_runs_with_the_jobs_only_tool(number, tmp_path, capsys):
    """No T word (most LinuxCNC samples, CAMotics, PyCAM): the job's one tool, whatever its number (T0
    too), is the one loaded and the summary says so; the result is the one of the same program with
    `T<n> M6` written at its start (same feeds, same cycle time)."""
    rc, summary, out = optimized(small_job(tmp_path, NO_T, tools=(number,), name="bare"))
    assert rc == 0, capsys.readouterr().err
    assert any(f"T{number}, the job's only tool, taken as loaded" in n for n in summary["notes"])
    rc2, with_t, out_t = optimized(small_job(tmp_path, f"T{number} M6\n" + NO_T, tools=(number,), name="t"))
    assert rc2 == 0
    assert f_words(out) == f_words(out_t) and len(f_words(out)) >= 2
    assert summary["cycle_time_after_s"] == with_t["cycle_time_after_s"]


def test_a_program_without_t_words_and_several_tools_says_what_to_write(tmp_path, capsys):
    d = small_job(tmp_path, NO_T, tools=(1, 2))
    assert optimized(d)[0] == 2
    err = capsys.readouterr().err
    assert (f"{d / 'p.nc'}:4: the program cuts before any T word selects a tool; the job describes [tools.1], "
            "[tools.2]: write `T<n> M6`") in err and "Traceback" not in err


def test_the_programs_own_t_word_replaces_the_assumed_tool():
    """The job's tool is assumed only until the program selects one: `T4` without M6 after the first
    rapid is the tool that cuts, and the rapid before it had none (Fusion's G28 before T1 M6: no note);
    `T0 M6` (the empty spindle on LinuxCNC) is kept as T0; a cut before the T word keeps the job's tool."""
    from millpost.gcode import ReaderOptions, read_text
    one = ReaderOptions.for_tools({3: 6.0})
    p = read_text("G0 X0 Y0 Z5\nT4\nG1 Z-1 F100\nT0 M6\nG1 X5\n", "p.nc", one)
    assert p.toolpath.tool.tolist() == [-1, 4, 0] and not any("only tool" in n for n in p.notes)
    p = read_text("G0 X0 Y0 Z5\nG1 Z-1 F100\nT4 M6\nG1 X5\n", "p.nc", one)
    assert p.toolpath.tool.tolist() == [3, 3, 4] and any("T3, the job's only tool" in n for n in p.notes)
    d = {3: 6.0, 4: 3.0}
    assert read_text("G0 X0 Y0 Z5\nG1 Z-1 F100\n", "p.nc", ReaderOptions.for_tools(d)).toolpath.tool.tolist() == [-1, -1]


def test_cutting_with_the_spindle_off_is_a_gate_with_a_stated_speed(tmp_path, capsys):
    """No M3 (a trim router switched by hand): refused naming the line and what to write; allowed
    without the job's spindle_rpm, refused again (no guessed speed); allowed with it, the result is the
    one of the same program with `S<rpm> M3` written (same feeds), and the notes say so."""
    no_m3 = NO_T.replace("S10000 M3\n", "")
    d = small_job(tmp_path, no_m3, name="off")
    assert optimized(d)[0] == 2
    err = capsys.readouterr().err
    line4 = no_m3.splitlines()[3].strip()
    assert (f"{d / 'p.nc'}:4: the tool cuts material with the spindle off (block '{line4}'): expected M3/M4 with "
            "S<rpm> before this line") in err and "--allow spindle-off" in err
    assert optimized(d, "--allow", "spindle-off")[0] == 2
    assert "its speed is unknown: give spindle_rpm = <rpm> in the job" in capsys.readouterr().err
    hand = small_job(tmp_path, no_m3, extra="spindle_rpm = 10000", name="hand")
    rc, summary, out = optimized(hand, "--allow", "spindle-off")
    assert rc == 0, capsys.readouterr().err
    assert any(n.startswith("warning (spindle-off, allowed)") for n in summary["notes"])
    assert any("turns at 10000 rpm" in n for n in summary["notes"])
    # the program's own S word (set without M3) is the speed when the job gives none
    rc, by_s, out_s = optimized(small_job(tmp_path, NO_T.replace(" M3", ""), name="s"), "--allow", "spindle-off")
    assert rc == 0 and any("the S word in force (S10000" in n for n in by_s["notes"])
    rc, _, out_m3 = optimized(small_job(tmp_path, NO_T, name="m3"))
    assert rc == 0 and f_words(out) == f_words(out_m3) == f_words(out_s)


def test_m3_without_an_s_word_is_an_unknown_speed_not_a_spindle_off(tmp_path, capsys):
    """`M3` with no S word in force runs the spindle at a speed the program does not give: refused as an
    unknown speed naming the M3's line (not as 'spindle off', which --allow would not cure); with the job's
    spindle_rpm it runs, without --allow, exactly as the same program with that S word written."""
    no_s = NO_T.replace("S10000 M3\n", "M3\n")
    m3_line = next(k for k, ln in enumerate(no_s.splitlines(), 1) if ln.strip() == "M3")
    d = small_job(tmp_path, no_s, name="nos")
    assert optimized(d)[0] == 2
    err = capsys.readouterr().err
    assert "unknown spindle speed" in err and f"the M3/M4 at line {m3_line} runs the spindle" in err
    assert "spindle off" not in err and "--allow" not in err
    rc, summary, out = optimized(small_job(tmp_path, no_s, extra="spindle_rpm = 10000", name="nos_rpm"))
    assert rc == 0, capsys.readouterr().err
    assert any(f"M3/M4 at line {m3_line}), it turns at 10000 rpm" in n for n in summary["notes"])
    rc, _, out_m3 = optimized(small_job(tmp_path, NO_T, name="m3s"))
    assert rc == 0 and f_words(out) == f_words(out_m3)


def test_spindle_rpm_out_of_range_is_refused(tmp_path, capsys):
    assert optimized(small_job(tmp_path, NO_T, extra="spindle_rpm = 0"))[0] == 2
    assert "spindle_rpm" in capsys.readouterr().err
