"""`millpost simulate`: trace contents against a closed-form slot, crash reporting, and real
third-party programs (CAMotics example projects, Fusion 360 posts) run without error."""

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from millpost.cli import main

DATA = Path(__file__).parents[2] / ".." / "shared" / "data"


def test_slot_trace_and_final_stock(tmp_path, capsys):
    nc = tmp_path / "slot.nc"
    nc.write_text("G21 G90 G17\nG0 X-5 Y10 Z5\nS12000 M3\nG1 Z-1.5 F300\nG1 X25 F600\nG0 Z5\nM30\n")
    trace, stl = tmp_path / "t.csv", tmp_path / "final.stl"
    rc = main(["simulate", str(nc), "--stock-box", "0,0,-10,20,20,0", "--cell", "0.025", "--tool-diameter", "6",
               "--trace", str(trace), "--stock-stl", str(stl), "--json"])
    assert rc == 0
    summary = json.loads(capsys.readouterr().out)
    # a 6 mm wide, 1.5 mm deep slot straight through the 20 mm block
    assert summary["removed_mm3"] == pytest.approx(20 * 6 * 1.5, rel=5e-3)
    assert summary["max_ap_mm"] == pytest.approx(1.5, abs=1e-4)
    rows = list(csv.DictReader(trace.open()))
    assert len(rows) == summary["samples"]
    mid = [r for r in rows if 5 < float(r["x_mm"]) < 15]
    assert mid and all(r["line"] == "5" for r in mid)
    assert np.mean([float(r["area_mm2"]) for r in mid]) == pytest.approx(6 * 1.5, rel=5e-3)
    assert np.mean([float(r["phi_st_deg"]) for r in mid]) == pytest.approx(0.0, abs=0.2)
    assert np.mean([float(r["phi_ex_deg"]) for r in mid]) == pytest.approx(180.0, abs=0.2)
    assert sum(float(r["volume_mm3"]) for r in rows) == pytest.approx(summary["removed_mm3"], rel=1e-6)
    m = trimesh.load(stl)
    assert m.is_watertight and m.volume == pytest.approx(20 * 20 * 10 - 180, rel=2e-2)


def test_job_with_two_tools(tmp_path, capsys):
    """A job file gives program, stock and tools by number: two slots cut by T1 (D6, 1 mm deep) and
    T2 (D3, 2 mm deep) through a 30 mm block remove 30·6·1 + 30·3·2 = 360 mm³, each at area 6 mm²."""
    (tmp_path / "p.nc").write_text(
        "G21 G90 G17\nT1 M6\nS10000 M3\nG0 X-5 Y5 Z5\nG1 Z-1 F300\nG1 X35 F600\nG0 Z5\n"
        "T2 M6\nS12000 M3\nG0 X-5 Y15\nG1 Z-2 F200\nG1 X35 F400\nG0 Z5\nM30\n")
    (tmp_path / "job.toml").write_text(
        'program = "p.nc"\nmaterial = "al6061"\nmachine = "vmc-small"\n[stock]\nbox = [[0, 0, -10], [30, 20, 0]]\n'
        'cell_mm = 0.05\n[tools.1]\ndiameter_mm = 6\nflutes = 3\n[tools.2]\ndiameter_mm = 3\nflutes = 2\n'
        '[limits]\nds_mm = 0.2\n')
    trace = tmp_path / "t.csv"
    assert main(["simulate", str(tmp_path), "--trace", str(trace), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["removed_mm3"] == pytest.approx(360.0, rel=5e-3)
    rows = list(csv.DictReader(trace.open()))
    assert np.median(np.diff([float(r["s_mm"]) for r in rows])) == pytest.approx(0.2, rel=0.05)  # the job's ds_mm
    for tool, line in (("1", "6"), ("2", "12")):
        mid = [float(r["area_mm2"]) for r in rows if r["tool"] == tool and r["line"] == line and 8 < float(r["x_mm"]) < 22]
        assert mid and np.mean(mid) == pytest.approx(6.0, rel=5e-3)
    # flags that the job already gives are refused, not silently ignored
    assert main(["simulate", str(tmp_path), "--stock-box", "0,0,-1,1,1,0", "--trace", str(trace)]) == 2
    assert "stock-box" in capsys.readouterr().err


def test_npz_trace_keeps_slices(tmp_path):
    nc = tmp_path / "ball.nc"
    nc.write_text("G21 G90\nG0 X-5 Y10 Z5\nG1 Z-2 F300\nG1 X25 F600\nM30\n")
    out = tmp_path / "t.npz"
    assert main(["simulate", str(nc), "--stock-box", "0,0,-10,20,20,0", "--cell", "0.05", "--tool-diameter", "6",
                 "--shape", "ball", "--slices", "4", "--trace", str(out)]) == 0
    z = np.load(out)
    assert z["phi_st"].shape[1] == 4 and z["line"].shape == z["ap_mm"].shape
    R, ap = 3.0, 2.0
    segment = R * R * math.acos((R - ap) / R) - (R - ap) * math.sqrt(2 * R * ap - ap * ap)
    mid = (z["xyz_mm"][:, 0] > 5) & (z["xyz_mm"][:, 0] < 15) & (z["xyz_mm"][:, 2] < -1)
    assert z["area_mm2"][mid].mean() == pytest.approx(segment, rel=5e-3)


def test_rapid_through_stock_is_an_error(tmp_path, capsys):
    nc = tmp_path / "crash.nc"
    nc.write_text("G21 G90\nG0 X-5 Y10 Z5\nG1 Z4 F300\nG0 Z-1\nG0 X25\nM30\n")
    rc = main(["simulate", str(nc), "--stock-box", "0,0,-10,20,20,0", "--cell", "0.1", "--tool-diameter", "6",
               "--trace", str(tmp_path / "t.csv")])
    assert rc == 2
    assert f"{nc}:5: rapid move runs into the stock" in capsys.readouterr().err
    assert not (tmp_path / "t.csv").exists()


def test_rapid_through_a_cut_through_slot_is_not_a_crash(tmp_path):
    """Cut a slot through a 1 mm plate (to Z-1.5), then rapid back along it at Z-1.2: below the
    stock's bottom, where the cut-through columns hold no material."""
    nc = tmp_path / "through.nc"
    nc.write_text("G21 G90\nS10000 M3\nG0 X-5 Y10 Z5\nG1 Z-1.5 F300\nG1 X25 F600\nG0 Z-1.2\nG0 X-5\nG0 Z5\nM30\n")
    assert main(["simulate", str(nc), "--stock-box", "0,0,-1,20,20,0", "--cell", "0.05", "--tool-diameter", "6",
                 "--trace", str(tmp_path / "t.csv")]) == 0


def test_bad_stock_box_is_a_config_error(tmp_path, capsys):
    nc = tmp_path / "a.nc"
    nc.write_text("G0 X0\n")
    rc = main(["simulate", str(nc), "--stock-box", "0,0,1", "--tool-diameter", "6", "--trace", str(tmp_path / "t.csv")])
    assert rc == 2 and "stock-box" in capsys.readouterr().err


CAMOTICS_SHAPES = {"cylindrical": "flat", "ballnose": "ball", "conical": "chamfer", "snubnose": "chamfer"}


def camotics_cases():
    base = DATA / "camotics" / "examples"
    if not base.is_dir():
        return []
    cases = []
    for proj in sorted(base.glob("*/*.camotics")):
        d = json.loads(proj.read_text())
        for f in d["files"]:
            if not f.endswith(".tpl"):  # .tpl is CAMotics' JavaScript toolpath language, not G-code
                cases.append(pytest.param(proj, f, id=f"{proj.stem}-{f}"))
    return cases


def camotics_tool_args(tool: dict) -> list[str]:
    k = 25.4 if tool.get("units") == "imperial" else 1.0
    D, L = tool["diameter"] * k, tool["length"] * k
    shape = CAMOTICS_SHAPES[tool["shape"]]
    args = ["--tool-diameter", f"{D}", "--shape", shape]
    if shape == "chamfer":
        tip = tool.get("snub_diameter", 0.0) * k
        args += ["--tip-angle", f"{2 * math.degrees(math.atan((D - tip) / 2 / L))}", "--tip-diameter", f"{tip}"]
    return args + ["--flute-length", f"{L}"]


# vcarve.camotics puts the workpiece top at Z+0.25 mm while vcarve.ngc rapids at Z0 between cuts:
# a genuine rapid through the top 0.25 mm (value: the lowest rapid height in the program, mm)
RAPID_CRASHES = {"vcarve.ngc": 0.0}


@pytest.mark.skipif(not (DATA / "camotics").is_dir(), reason="../shared/data/camotics not present")
@pytest.mark.parametrize("proj,fname", camotics_cases())
def test_camotics_examples_simulate(proj, fname, tmp_path, capsys):
    from millpost.errors import ParseError
    from millpost.gcode import read_program

    d = json.loads(proj.read_text())
    try:
        prog = read_program(proj.parent / fname)
    except ParseError as exc:
        pytest.skip(f"the G-code reader refuses this file: {exc}")
    used = [str(t) for t in prog.tools] or list(d["tools"])
    tool = d["tools"].get(used[0], next(iter(d["tools"].values())))
    lo, hi = d["workpiece"]["bounds"]["min"], d["workpiece"]["bounds"]["max"]
    box = ",".join(f"{v}" for v in (*lo, *hi))
    trace = tmp_path / "t.csv"
    rc = main(["simulate", str(proj.parent / fname), f"--stock-box={box}", "--cell", "0.1", "--step", "0.25",
               *camotics_tool_args(tool), "--trace", str(trace), "--json"])
    captured = capsys.readouterr()
    if fname in RAPID_CRASHES:
        # a genuine crash: the project's workpiece top stands above where the program rapids
        assert rc == 2 and "rapid move runs into the stock" in captured.err
        crash_z = float(captured.err.split(" Z")[-1].split()[0])
        assert crash_z < hi[2] and crash_z >= RAPID_CRASHES[fname]
        return
    assert rc == 0, captured.err
    summary = json.loads(captured.out)
    assert summary["removed_mm3"] > 0 and summary["cutting_samples"] > 0


@pytest.mark.skipif(not (DATA / "fusion-ledfloor").is_dir(), reason="../shared/data/fusion-ledfloor not present")
@pytest.mark.parametrize("name,dia,thick,top", [
    ("1024_block_14bit", 1.4, 6.0, 0.0), ("1055_utab_265bit", 2.65, 12.55, 0.0), ("1117_wall_28bit", 2.8, 12.55, 0.0),
    ("1071_surface_40mm_10overlap", 40, 12.55, 0.5)])
def test_fusion_programs_simulate(name, dia, thick, top, tmp_path, capsys):
    """Plywood stock (thickness from the author's log) under the program's XY extent; the facing
    program cuts at Z0, so its stock is given 0.5 mm to skim. The bits cut through the plywood in
    the author's log, so their flutes are longer than the stock is thick."""
    from millpost.gcode import read_program

    path = DATA / "fusion-ledfloor" / f"{name}.nc"
    bb = read_program(path).toolpath.bbox()
    box = f"{bb[0, 0] - 1},{bb[0, 1] - 1},{-thick},{bb[1, 0] + 1},{bb[1, 1] + 1},{top}"
    rc = main(["simulate", str(path), f"--stock-box={box}", "--cell", "0.1", "--step", "0.25", "--tool-diameter",
               f"{dia}", "--flute-length", f"{thick + 1}", "--trace", str(tmp_path / "t.csv"), "--json"])
    captured = capsys.readouterr()
    assert rc == 0, captured.err
    assert json.loads(captured.out)["removed_mm3"] > 0
