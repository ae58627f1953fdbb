"""Calibration programs and their plan: what every line is meant to produce.

Three parts, each optional, in one program for one tool in a block of stock (the stock's top at z1):

- idle: the spindle at each speed for a few seconds in the air (no-load power and current vs rpm);
- slot series (the average-force method, Altintas ch. 2): full slots along +X right through the stock at
  every feed per tooth and depth asked, one slot per Y position, entering and leaving in the air so that
  the middle of each slot is a steady cut of known engagement (ae = D);
- stepped engagement: side cuts along +X on the stock's +Y face (climb milling with M3: the material on
  the right of the travel), widening in steps of ae at a depth ap, then the next depth in a fresh segment
  of the stock; the ladder stops before the first step whose predicted load (peak in-plane force over
  the tool's breaking force, tool deflection over the limit, cutting power over the spindle's) exceeds
  `margin` of its limit;
- axis test: back-and-forth strokes of every axis in the air above the stock at several feeds, long
  (cruise: friction) and short (mostly acceleration: inertia), for drive mass and friction.

The program is written in a chosen dialect (`millpost.gcode.convert`), the plan as a CSV with one row per
planned move: the source line, the kind, and the engagement and conditions it should produce.
"""

from __future__ import annotations

import csv
import io
from dataclasses import asdict, dataclass, fields, replace
from pathlib import Path

import numpy as np

from ..errors import MillpostError, ParseError
from ..files import write_atomic
from ..forces import given_cut
from ..gcode import ReaderOptions, read_text
from ..gcode import dialects
from ..gcode.convert import convert
from ..machine import Machine
from ..materials import Material
from ..tools.beam import ToolBeam
from ..tools.cutter import Tool

KINDS = ("idle", "slot", "step", "axis")
CLEAR_MM = 2.0          # air between the tool and the stock where cuts start and end
SAFE_MM = 5.0           # rapid height above the stock


@dataclass(frozen=True)
class PlannedMove:
    """One planned move: its source line (filled when written), kind, the tool, and what it should do.
    Lengths mm, feed mm/min, speed rpm; axis: the axis an axis-test stroke moves ('' otherwise)."""

    kind: str
    line: int
    diameter_mm: float
    flutes: int
    helix_deg: float
    ae_mm: float
    ap_mm: float
    fz_mm: float
    rpm: float
    feed_mm_min: float
    climb: int
    axis: str
    x0_mm: float
    y0_mm: float
    z0_mm: float
    x1_mm: float
    y1_mm: float
    z1_mm: float
    dwell_s: float = 0.0


@dataclass
class Plan:
    """A calibration program (text in its dialect) and its planned moves."""

    text: str
    moves: list[PlannedMove]
    dialect: str
    notes: list[str]

    def write(self, folder: str | Path, tool: Tool, material: str, machine: str,
              stock: tuple[tuple[float, float, float], tuple[float, float, float]], *, tool_number: int = 1,
              cell_mm: float = 0.05, ds_mm: float = 0.2) -> Path:
        """The program (calibration.nc), the plan (plan.csv) and a job (job.toml) naming them, the
        material, machine, stock and tool, in `folder`: what `calibrate fit --plan` and `optimize` read."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        write_atomic(folder / "calibration.nc", self.text)
        write_plan(folder / "plan.csv", self.moves)
        fields_ = {k: v for k, v in asdict(tool).items() if v is not None and k not in ("number", "name")}
        job = {"program": "calibration.nc", "dialect": self.dialect, "material": material, "machine": machine,
               "stock": {"box": [list(stock[0]), list(stock[1])], "cell_mm": cell_mm},
               "tools": {str(tool_number): fields_}, "limits": {"ds_mm": ds_mm}}
        from ..config import dump_toml
        write_atomic(folder / "job.toml", "# millpost calibration job (millpost calibrate plan)\n" + dump_toml(job))
        return folder


def write_plan(path: str | Path, moves: list[PlannedMove]) -> None:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    names = [f.name for f in fields(PlannedMove)]
    w.writerow(names)
    for m in moves:
        w.writerow([f"{v:.6g}" if isinstance(v, float) else v for v in asdict(m).values()])
    write_atomic(path, buf.getvalue())


def read_plan(path: str | Path) -> list[PlannedMove]:
    """Read a plan CSV; errors name file:row:column."""
    name = str(path)
    rows = list(csv.reader(Path(path).read_text().splitlines()))
    names = [f.name for f in fields(PlannedMove)]
    if not rows or rows[0] != names:
        raise ParseError("not a calibration plan header", file=name, line=1, column=1,
                         word=",".join(rows[0])[:40] if rows else "", expected=",".join(names))
    out = []
    types = {f.name: f.type for f in fields(PlannedMove)}
    for lineno, row in enumerate(rows[1:], start=2):
        if len(row) != len(names):
            raise ParseError(f"{len(row)} fields, the header has {len(names)}", file=name, line=lineno, column=1,
                             expected=f"{len(names)} values")
        values, col = {}, 1
        for text, key in zip(row, names):
            try:
                values[key] = text if types[key] == "str" else int(text) if types[key] == "int" else float(text)
            except ValueError:
                raise ParseError(f"bad {key}", file=name, line=lineno, column=col, word=text,
                                 expected="an integer" if types[key] == "int" else "a number") from None
            col += len(text) + 1
        if values["kind"] not in KINDS:
            raise ParseError("unknown kind", file=name, line=lineno, column=1,
                             word=values["kind"], expected=" or ".join(KINDS))
        out.append(PlannedMove(**values))
    return out


@dataclass(frozen=True)
class PlanRequest:
    """What to plan. Stock box mm (program frame); rpm; slot feeds per tooth and depths (mm); stepped
    engagement feed per tooth (mm, None: the material's mid chip load); margin: fraction of each limit
    the stepped ladder may reach; axis test: feeds as fractions of each axis's maximum; idle speeds rpm."""

    stock: tuple[tuple[float, float, float], tuple[float, float, float]]
    rpm: float
    slot_fz_mm: tuple[float, ...] = ()
    slot_ap_mm: tuple[float, ...] = ()
    step_fz_mm: float | None = None
    steps: bool = True
    margin: float = 0.8
    deflection_mm: float = 0.025
    axis_test: bool = True
    axis_fractions: tuple[float, ...] = (0.1, 0.25, 0.5, 0.75, 1.0)
    idle_rpm: tuple[float, ...] = ()
    idle_s: float = 3.0


class _Writer:
    """Canonical G-code (mm, absolute) with the planned move of every motion (None: unplanned) and of
    every dwell."""

    def __init__(self, tool: Tool, tool_number: int) -> None:
        self.tool = tool
        self.lines = ["G21 G90 G94 G17", f"T{tool_number} M6"]
        self.motions: list[PlannedMove | None] = []
        self.dwells: list[PlannedMove | None] = []
        self.pos = (0.0, 0.0, 0.0)

    def rapid(self, x, y, z) -> None:
        self.lines.append(f"G0 X{x:.4f} Y{y:.4f} Z{z:.4f}")
        self.motions.append(None)
        self.pos = (x, y, z)

    def feed(self, x, y, z, feed, plan: PlannedMove | None = None) -> None:
        self.lines.append(f"G1 X{x:.4f} Y{y:.4f} Z{z:.4f} F{feed:.1f}")
        self.motions.append(plan)
        self.pos = (x, y, z)

    def dwell(self, seconds: float, plan: PlannedMove | None = None) -> None:
        self.lines.append(f"G4 P{seconds:g}")
        self.dwells.append(plan)

    def other(self, text: str) -> None:
        self.lines.append(text)

    def move(self, kind, x0, y0, z0, x1, y1, z1, *, ae=0.0, ap=0.0, fz=0.0, rpm=0.0, feed=0.0, axis="",
             dwell=0.0) -> PlannedMove:
        t = self.tool
        return PlannedMove(kind, 0, t.diameter_mm, t.flutes, t.helix_deg, ae, ap, fz, rpm, feed, 1, axis,
                           x0, y0, z0, x1, y1, z1, dwell)


def predicted_ratios(tool: Tool, material: Material, machine: Machine, ae_mm, ap_mm, fz_mm, rpm: float,
                     deflection_mm: float) -> np.ndarray:
    """(N, 3) predicted load over limit of cuts along +X (climb): peak in-plane force / the tool's breaking
    force, the tool's tip deflection / deflection_mm, cutting power / the spindle's power at rpm. (The
    machine's own compliance is left out: it bends the result, not the tool.)"""
    eng = given_cut(tool, ae_mm, ap_mm)
    loads = material.force_model("mechanistic").predict(eng, fz_mm, rpm, tool, peaks=True)
    beam = ToolBeam.of(tool)
    defl = loads.peak_force_xy_N * beam.compliance_mm_per_N(eng.ap_mm, at_tip=True)
    return np.column_stack([loads.peak_force_xy_N / beam.breaking_force_N(eng.ap_mm), defl / deflection_mm,
                            loads.power_W / machine.spindle.power_available_W(rpm)])


def make_plan(tool: Tool, material: Material, machine: Machine, request: PlanRequest, *, dialect: str = "linuxcnc",
              tool_number: int = 1) -> Plan:
    """The calibration program and plan (see the module's docstring)."""
    (x0, y0, z0), (x1, y1, z1) = request.stock
    if not (x1 > x0 and y1 > y0 and z1 > z0):
        raise MillpostError(f"stock box {request.stock}: needs max > min on every axis")
    rpm = float(np.clip(request.rpm, machine.spindle.rpm_min, machine.spindle.rpm_max))
    notes = [] if rpm == request.rpm else [f"S{request.rpm:g} is outside the spindle's range: S{rpm:g} used"]
    D, R = tool.diameter_mm, tool.radius_mm
    safe = z1 + SAFE_MM
    w = _Writer(tool, tool_number)
    feed_max = machine.feed_max_mm_min
    # idle: spindle speeds in the air
    xa, ya = x0 - R - CLEAR_MM, y0 - R - CLEAR_MM
    w.rapid(xa, ya, safe)
    for n in request.idle_rpm:   # a short move in the air on each side of the dwell carries its speed
        n = float(np.clip(n, machine.spindle.rpm_min, machine.spindle.rpm_max))
        w.other(f"S{n:.0f} M3")
        w.feed(xa, ya, safe + 1.0, 600.0)
        w.dwell(request.idle_s, w.move("idle", *w.pos, *w.pos, rpm=n, dwell=request.idle_s))
        w.feed(xa, ya, safe, 600.0)
    band = min(0.25 * (y1 - y0), 2.0 * D) if request.steps else 0.0  # the steps' band along the +Y face
    _slots(w, tool, material, machine, request, rpm, y1 - band - (CLEAR_MM if band else 0.0))
    if request.steps:
        _steps(w, tool, material, machine, request, rpm, band, notes)
    if request.axis_test:
        _axis_test(w, machine, request, feed_max)
    w.other("M5")
    canonical = "\n".join(w.lines) + "\nM2\n"
    return _post(canonical, w, dialect, notes)


def _slots(w: _Writer, tool: Tool, material: Material, machine: Machine, req: PlanRequest, rpm: float,
           y1: float) -> None:
    """Slots in y0..y1 of the stock."""
    (x0, y0, _), (x1, _, z1) = req.stock
    D, R = tool.diameter_mm, tool.radius_mm
    cuts = [(ap, fz) for ap in req.slot_ap_mm for fz in req.slot_fz_mm]
    if not cuts:
        return
    pitch = D + max(2.0, 0.25 * D)
    margin = 0.5 * (pitch - D)           # stock left between the first slot and the stock's edge
    room = y1 - y0 - D - margin
    fits = int(np.floor(room / pitch)) + 1 if room >= 0 else 0
    if len(cuts) > fits:
        raise MillpostError(f"the slots have {y1 - y0:g} mm of the stock in Y (the rest is for the stepped "
                            f"passes): room for {fits} slots of D{D:g} {pitch - D:g} mm apart, {len(cuts)} asked "
                            f"({len(req.slot_ap_mm)} depths × {len(req.slot_fz_mm)} feeds); give a wider stock or "
                            "fewer feeds or depths")
    ratios = predicted_ratios(tool, material, machine, np.full(len(cuts), D), [c[0] for c in cuts],
                              np.array([c[1] for c in cuts]), rpm, req.deflection_mm)
    over = ratios[:, [0, 2]].max(axis=1) > 1.0   # breakage and spindle power; deflection only bends a slot
    if over.any():
        k = int(np.flatnonzero(over)[0])
        raise MillpostError(f"slot ap {cuts[k][0]:g} mm at fz {cuts[k][1]:g} mm is predicted at "
                            f"{ratios[k, [0, 2]].max():.0%} of a limit (force/breaking, tool deflection, spindle power "
                            f"{', '.join(f'{r:.0%}' for r in ratios[k])}); use smaller depths or feeds")
    w.other(f"S{rpm:.0f} M3")
    xs, xe = x0 - R - CLEAR_MM, x1 + R + CLEAR_MM
    for i, (ap, fz) in enumerate(cuts):
        y = y0 + R + margin + i * pitch
        z = z1 - ap
        feed = min(fz * tool.flutes * rpm, machine.feed_max_mm_min)
        w.rapid(xs, y, z1 + SAFE_MM)
        w.rapid(xs, y, z1 + 1.0)
        w.feed(xs, y, z, min(feed, 300.0))
        w.feed(xe, y, z, feed, w.move("slot", xs, y, z, xe, y, z, ae=D, ap=ap, fz=feed / (tool.flutes * rpm),
                                      rpm=rpm, feed=feed))
        w.rapid(xe, y, z1 + SAFE_MM)


def _steps(w: _Writer, tool: Tool, material: Material, machine: Machine, req: PlanRequest, rpm: float,
           room: float, notes: list[str]) -> None:
    """The stepped ladder on the +Y face, at most `room` mm deep into it."""
    (x0, y0, _), (x1, y1, z1) = req.stock
    D, R = tool.diameter_mm, tool.radius_mm
    fz = req.step_fz_mm or float(np.mean(material.chip_load_mm(D)))
    feed = min(fz * tool.flutes * rpm, machine.feed_max_mm_min)
    fz = feed / (tool.flutes * rpm)
    aps = [a * D for a in (0.25, 0.5, 1.0, 1.5, 2.0) if a * D <= tool.flute_len]
    aes = [a * D for a in (0.05, 0.1, 0.2, 0.35, 0.5, 0.75)]
    segments = min(len(aps), int((x1 - x0) // (6 * D)))   # a fresh segment per depth, cuts ≥ 4 D long
    if segments < 1:
        notes.append("stepped engagement skipped: the stock is shorter than 6 tool diameters in X")
        return
    aps = aps[:segments]
    seg_len = (x1 - x0) / segments
    w.other(f"S{rpm:.0f} M3")
    for j, ap in enumerate(aps):
        ladder = []
        width = 0.0
        limited = False
        for ae in aes:
            if width + ae > room:
                break
            ratio = predicted_ratios(tool, material, machine, ae, ap, fz, rpm, req.deflection_mm)[0]
            if ratio.max() > req.margin:
                limited = True
                notes.append(f"stepped engagement stops before ae {ae:g} ap {ap:g} mm: predicted "
                             f"{ratio.max():.0%} of a limit (margin {req.margin:.0%})")
                break
            ladder.append(ae)
            width += ae
        if not ladder:
            break
        xa, xb = x0 + j * seg_len + R, x0 + (j + 1) * seg_len - R
        z = z1 - ap
        face = y1
        for ae in ladder:
            yc = face + R - ae
            y_out = y1 + R + CLEAR_MM
            w.rapid(xa, y_out, z1 + SAFE_MM)
            w.rapid(xa, y_out, z1 + 1.0)
            w.feed(xa, y_out, z, min(feed, 300.0))
            w.feed(xa, yc, z, feed * 0.5)  # radial entry into the face
            w.feed(xb, yc, z, feed, w.move("step", xa, yc, z, xb, yc, z, ae=ae, ap=ap, fz=fz, rpm=rpm, feed=feed))
            w.rapid(xb, yc, z1 + SAFE_MM)
            face -= ae
        if limited:
            break


def _axis_test(w: _Writer, machine: Machine, req: PlanRequest, feed_max: float) -> None:
    (x0, y0, _), (x1, y1, z1) = req.stock
    safe = z1 + SAFE_MM
    cx, cy = 0.5 * (x0 + x1), 0.5 * (y0 + y1)
    w.other("M5")
    for axis, span in (("x", x1 - x0), ("y", y1 - y0), ("z", min(20.0, 0.5 * (x1 - x0)))):
        a = machine.axes[axis]
        for frac in req.axis_fractions:
            f = frac * a.vmax_mm_min
            v = f / 60.0
            short = min(0.5 * v * v / a.amax_mm_s2, 0.5 * span)  # accelerate and stop: no cruise
            for length in (span, short):
                if length < 0.05:
                    continue
                start = {"x": (cx - 0.5 * length, cy, safe), "y": (cx, cy - 0.5 * length, safe),
                         "z": (cx, cy, safe)}[axis]
                end = {"x": (cx + 0.5 * length, cy, safe), "y": (cx, cy + 0.5 * length, safe),
                       "z": (cx, cy, safe + length)}[axis]
                w.rapid(*start)
                for p, q in ((start, end), (end, start)):
                    w.feed(*q, f, w.move("axis", *p, *q, feed=f, axis=axis))


def _post(canonical: str, w: _Writer, dialect: str, notes: list[str]) -> Plan:
    """The canonical program in the target dialect, and the plan rows with the lines they landed on."""
    program = read_text(canonical, "<calibration>", ReaderOptions(dialect="linuxcnc"))
    target = dialects.get(dialect)
    text = convert(program, target).replace(f"converted by millpost from <calibration> [linuxcnc to {target.name}]",
                                            "millpost calibration program")
    out = read_text(text, "<calibration>", ReaderOptions(dialect=target.name))
    dwell_lines = [e.line for e in out.events if e.kind == "dwell"]
    if len(out.toolpath) != len(w.motions) or len(dwell_lines) != len(w.dwells):
        raise MillpostError("internal: the converted calibration program changed its moves")
    moves = [replace(p, line=int(out.toolpath.line[k])) for k, p in enumerate(w.motions) if p is not None]
    moves += [replace(p, line=int(line)) for line, p in zip(dwell_lines, w.dwells) if p is not None]
    return Plan(text, sorted(moves, key=lambda m: m.line), target.name, notes)
