"""Chatter in a program: each cutting sample's axial depth against the limiting (stable) depth at its
spindle speed and immersion, for the tools whose tip FRF the job gives (`Job.frf`).

The limit is the zero-order stability lobe (`lobes.zero_order_limit_mm`, Altintas & Budak 1995) of the
sample's radial immersion φ_st…φ_ex (the outermost engaged arc over the flank's axial slices, rad) at the
speed the spindle runs (rpm), with the cutting coefficients K_t = K_tc and K_r = K_rc/K_tc of the material's
mechanistic model (`Mechanistic.from_material`: its published set, or the tangent of its Kienzle law).
The lobes take x as the feed direction: where the feed runs nearer machine Y than X the two directions'
FRFs swap (cross terms neglected, as in the lobes; exact for a round tool, whose X and Y are the same).

Chatter is a quality limit: feed does not change it (depth and speed do), so it lowers no feed; the lines
cut above the stable depth are reported (`Chatter`), and `[limits] rpm = "optimize"` prefers speeds that
clear them (`scan_speeds`). Cost: samples are grouped by tool, immersion and direction; one lobe
evaluation per group. The immersion is binned relative to its own width w: φ_st is rounded down and φ_ex up
to multiples of h = `ARC_WIDENING`/2 · 2^⌊log₂ w⌋ (w at least `ARC_MIN_DEG`), so the checked arc contains
the engaged one and is wider by less than `ARC_WIDENING`·w (1 %). a_lim changes about as much: within 3 %
for the arcs of flank cuts (0…φ_s up, π − φ_s…π down milling, 0.5…180°; chatter_slot's FRF, 6000–30000
rpm, `tests/stability/test_chatter_optimize.py`). Inside the range, where the zero-order method's two
roots nearly meet (e.g. 15.4° from 133°), a 1 % wider arc has moved it by up to 11 % (either way).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from ..forces.mechanistic import Mechanistic
from ..job import Job
from ..limits import QUALITY, Kind
from ..materials import Material
from ..signals import running_rpm
from ..toolpath import RAPID, Samples
from .frf import ToolTipFRF
from .lobes import zero_order_limit_mm

ARC_WIDENING = 0.01         # the checked arc is wider than the engaged one by less than this fraction
ARC_MIN_DEG = 0.05          # arcs narrower than this (degrees) are checked as this wide
SCAN_SPEEDS = 121           # speeds scanned across an S block's window for stable pockets
POCKETS = 3                 # pocket speeds added to an S block's candidates
LINES_LISTED = 200          # lines listed in the summary (their count is given)


def cutting_coefficients(material: Material) -> tuple[float, float]:
    """(K_t N/mm², K_r = K_rc/K_tc) of a material (its mechanistic set, or its Kienzle tangent)."""
    ktc, krc = Mechanistic.from_material(material).coef_[:2]
    return float(ktc), float(krc / ktc)


def binned_arc(phi_st, phi_ex) -> tuple[np.ndarray, np.ndarray]:
    """The arcs (rad, arrays) the check takes for engaged arcs φ_st…φ_ex (rad): at least `ARC_MIN_DEG` wide,
    φ_st rounded down and φ_ex up to multiples of h = `ARC_WIDENING`/2 · 2^⌊log₂ w⌋ (w the arc's width),
    within 0…π: they contain the engaged arc and are wider by less than `ARC_WIDENING`·w."""
    w_min = math.radians(ARC_MIN_DEG)
    st = np.minimum(np.asarray(phi_st, float), math.pi - w_min)
    ex = np.maximum(np.asarray(phi_ex, float), st + w_min)
    h = 0.5 * ARC_WIDENING * 2.0 ** np.floor(np.log2(ex - st))
    return np.maximum(np.floor(st / h + 1e-9) * h, 0.0), np.minimum(np.ceil(ex / h - 1e-9) * h, math.pi)


@dataclass(frozen=True)
class CutImmersion:
    """Per sample (N) what the stability limit depends on besides the speed: tool, the arc checked φ_st…φ_ex
    (rad, `binned_arc`; nan where the flank cuts nothing or the tool has no FRF), axial depth ap_mm and
    along_y (the feed runs nearer machine Y than X). Taken from the engagement before its per-slice arrays
    are released; the speeds may change after."""

    tool: np.ndarray
    phi_st: np.ndarray
    phi_ex: np.ndarray
    ap_mm: np.ndarray
    along_y: np.ndarray

    @classmethod
    def of(cls, job: Job, samples: Samples, eng) -> "CutImmersion | None":
        """The immersion of the samples whose tool has an FRF; None when no tool of the job has one."""
        if not job.frf:
            return None
        cuts = np.isfinite(eng.phi_st) & np.isfinite(eng.phi_ex) & (eng.dz_mm > 0)
        with np.errstate(invalid="ignore"):
            st = np.clip(np.where(cuts, eng.phi_st, np.inf).min(axis=1, initial=np.inf), 0.0, np.pi)
            ex = np.clip(np.where(cuts, eng.phi_ex, -np.inf).max(axis=1, initial=-np.inf), 0.0, np.pi)
        ok = (cuts.any(axis=1) & (samples.kind != RAPID) & (eng.ap_mm > 0)
              & np.isin(samples.tool, list(job.frf)))
        lo, hi = binned_arc(np.where(ok, st, 0.0), np.where(ok, ex, np.pi))
        along_y = np.abs(eng.feed_dir[:, 1]) > np.abs(eng.feed_dir[:, 0])
        return cls(samples.tool.astype(int), np.where(ok, lo, np.nan), np.where(ok, hi, np.nan),
                   np.asarray(eng.ap_mm, float), along_y)

    @property
    def checked(self) -> np.ndarray:
        """Samples with a stability limit (their tool has an FRF and the flank cuts)."""
        return np.isfinite(self.phi_st)

    def groups(self, job: Job, index: np.ndarray):
        """(FRF in the feed frame, tool, φ_st, φ_ex rad, the samples of `index` in the group) per group of
        checked samples at `index`."""
        index = index[self.checked[index]]
        keys = np.stack([self.tool[index], self.phi_st[index], self.phi_ex[index], self.along_y[index]], axis=1)
        if not len(keys):
            return
        uniq, inverse = np.unique(keys, axis=0, return_inverse=True)
        order = np.argsort(inverse.reshape(-1), kind="stable")
        bounds = np.searchsorted(inverse.reshape(-1)[order], np.arange(len(uniq) + 1))
        for g, (tool, lo, hi, y) in enumerate(uniq):
            at = index[order[bounds[g]:bounds[g + 1]]]
            yield job.frf[int(tool)].oriented(bool(y)), int(tool), float(lo), float(hi), at


def limit_mm(frf: ToolTipFRF, material: Material, flutes: int, phi_st: float, phi_ex: float, rpm) -> np.ndarray:
    """The zero-order limiting depth a_lim (mm) at the speeds `rpm` of a cut over [φ_st, φ_ex] (rad) with
    the tool tip's receptance `frf` in the feed frame (`ToolTipFRF.oriented`) and the material's cutting
    coefficients (`cutting_coefficients`)."""
    kt, kr = cutting_coefficients(material)
    return zero_order_limit_mm(frf, kt_N_per_mm2=kt, kr=kr, flutes=flutes, phi_st_rad=phi_st, phi_ex_rad=phi_ex,
                               rpm=rpm)


def _limit(job: Job, frf: ToolTipFRF, tool: int, phi_st: float, phi_ex: float, rpm: np.ndarray) -> np.ndarray:
    """a_lim (mm) of one group at the speeds `rpm`."""
    return limit_mm(frf, job.material, job.tools[tool].flutes, phi_st, phi_ex, rpm)


def limiting_depth_mm(job: Job, cut: CutImmersion, rpm: np.ndarray) -> np.ndarray:
    """Per sample the limiting axial depth (mm) at its spindle speed `rpm` (as programmed; run at the
    spindle's range, `running_rpm`); inf where it is not checked or the spindle stands."""
    out = np.full(len(cut.tool), np.inf)
    speed = running_rpm(job, rpm)
    for frf, tool, st, ex, at in cut.groups(job, np.flatnonzero(speed > 0)):
        speeds, back = np.unique(speed[at], return_inverse=True)
        out[at] = _limit(job, frf, tool, st, ex, speeds)[back.reshape(-1)]
    return out


def margin(job: Job, cut: CutImmersion, index: np.ndarray, rpm: np.ndarray) -> np.ndarray:
    """Per speed of `rpm` the smallest a_lim / ap over the checked samples at `index` (≥ 1: all stable;
    inf when none is checked)."""
    out = np.full(len(rpm), np.inf)
    for frf, tool, st, ex, at in cut.groups(job, index):
        out = np.minimum(out, _limit(job, frf, tool, st, ex, rpm) / cut.ap_mm[at].max())
    return out


@dataclass(frozen=True)
class SpeedScan:
    """An S block's chatter margin (smallest a_lim / ap over its samples) at its candidate speeds
    (`speeds` rpm, `margins`) and at its programmed speed (`programmed`)."""

    speeds: np.ndarray
    margins: np.ndarray
    programmed: float

    @property
    def clears(self) -> np.ndarray:
        return self.margins >= 1.0


def scan_speeds(job: Job, cut: CutImmersion | None, index: np.ndarray, grid: np.ndarray, programmed_rpm: float
                ) -> SpeedScan | None:
    """The candidate speeds of an S block (its samples `index`, window [grid[0], grid[-1]] rpm): `grid`
    plus the centres of its stable pockets (the speed of largest margin in each run of speeds where every
    sample is stable, among `SCAN_SPEEDS` spread geometrically; the `POCKETS` of largest margin), with the
    margins there. None when none of its samples is checked."""
    if cut is None or not cut.checked[index].any():
        return None
    programmed = float(running_rpm(job, np.array([programmed_rpm]))[0])
    scan = np.unique(np.concatenate([np.round(np.geomspace(grid[0], grid[-1], SCAN_SPEEDS)), grid, [programmed]]))
    m = margin(job, cut, index, scan)
    stable = (m >= 1.0) & (scan >= grid[0]) & (scan <= grid[-1])
    edges = np.flatnonzero(np.diff(np.concatenate([[0], stable.astype(int), [0]])))
    pockets = [a + int(np.argmax(m[a:b])) for a, b in zip(edges[::2], edges[1::2])]
    best = sorted(pockets, key=lambda i: -m[i])[:POCKETS]
    speeds = np.unique(np.concatenate([grid, scan[best]]))
    return SpeedScan(speeds, m[np.searchsorted(scan, speeds)], float(m[np.searchsorted(scan, programmed)]))


@dataclass
class Chatter:
    """The chatter check of a run: per sample (N) line, tool, speed (rpm, as the spindle runs it), axial
    depth ap_mm and limiting depth a_lim_mm (inf where not checked). A quality limit: reported per line."""

    line: np.ndarray
    tool: np.ndarray
    rpm: np.ndarray
    ap_mm: np.ndarray
    a_lim_mm: np.ndarray
    kt_N_per_mm2: float
    kr: float
    tools: tuple[int, ...]
    cut: CutImmersion
    remarks: tuple[str, ...] = ()
    name: ClassVar[str] = "chatter"
    kind: ClassVar[Kind] = QUALITY

    @classmethod
    def check(cls, job: Job, cut: CutImmersion | None, samples: Samples) -> "Chatter | None":
        """The check at the samples' speeds; None without an FRF."""
        if cut is None:
            return None
        a_lim = limiting_depth_mm(job, cut, samples.rpm)
        return cls(samples.line, cut.tool, running_rpm(job, samples.rpm), cut.ap_mm, a_lim,
                   *cutting_coefficients(job.material), tuple(sorted(job.frf)), cut, _remarks(job, cut))

    @property
    def over(self) -> np.ndarray:
        """Samples cut deeper than their stable depth."""
        return self.ap_mm > self.a_lim_mm

    def trace_columns(self) -> dict[str, np.ndarray]:
        """The trace's chatter columns per sample: the speed the spindle runs (rpm), the limiting depth
        (mm; inf where not checked), the arc checked φ_st…φ_ex (degrees, `binned_arc`; nan where not checked),
        feed_along_y (1: the FRF's X and Y swapped for it) and chatter_over (1: cut above a_lim)."""
        return {"rpm": self.rpm, "a_lim_mm": self.a_lim_mm,
                "phi_st_deg": np.degrees(self.cut.phi_st), "phi_ex_deg": np.degrees(self.cut.phi_ex),
                "feed_along_y": self.cut.along_y.astype(np.int8), "chatter_over": self.over.astype(np.int8)}

    def lines(self) -> list[dict]:
        """Per source line cut above its stable depth, its worst sample: tool, rpm, ap, a_lim (mm), ratio."""
        over = np.flatnonzero(self.over)
        ratio = self.ap_mm[over] / self.a_lim_mm[over]
        order = np.lexsort((-ratio, self.line[over]))
        first = order[np.concatenate([[True], np.diff(self.line[over][order]) != 0])] if len(order) else order
        return [{"line": int(self.line[over[k]]), "tool": int(self.tool[over[k]]), "rpm": round(float(self.rpm[over[k]]), 1),
                 "ap_mm": round(float(self.ap_mm[over[k]]), 3), "a_lim_mm": round(float(self.a_lim_mm[over[k]]), 3),
                 "ratio": round(float(ratio[k]), 3)} for k in first]

    def summary(self) -> dict:
        """The summary's "chatter" entry: the method, coefficients, checked tools and the lines over."""
        rows = self.lines()
        return {"kind": str(self.kind), "method": "zero-order stability lobes (Altintas & Budak 1995)",
                "kt_N_mm2": round(self.kt_N_per_mm2, 3), "kr": round(self.kr, 4), "tools": list(self.tools),
                "checked_samples": int(np.isfinite(self.a_lim_mm).sum()), "samples_over": int(self.over.sum()),
                "line_count": len(rows), "lines": rows[:LINES_LISTED]}

    def notes(self) -> list[str]:
        """The remarks on the FRFs (`_remarks`), then a warning per tool and speed whose lines are cut above
        the stable depth."""
        out = list(self.remarks)
        rows = self.lines()
        for tool, rpm in sorted({(r["tool"], r["rpm"]) for r in rows}):
            mine = [r for r in rows if r["tool"] == tool and r["rpm"] == rpm]
            worst = max(mine, key=lambda r: r["ratio"])
            shown = ", ".join(str(r["line"]) for r in mine[:10]) + (f" and {len(mine) - 10} more" if len(mine) > 10 else "")
            out.append(f"warning: chatter: T{tool} at {rpm:g} rpm cuts above its stable depth on lines {shown}: up to "
                       f"{worst['ap_mm']:g} mm deep where {worst['a_lim_mm']:g} mm is stable ({worst['ratio']:.2f}x, line "
                       f"{worst['line']}); a lighter depth or a speed in a stable pocket (rpm = \"optimize\") clears it")
        return out


def _remarks(job: Job, cut: CutImmersion) -> tuple[str, ...]:
    """Notes on the job's FRFs: a measured table's doubts (`DirectionFRF.doubts`) and a tool with an FRF
    that cuts nothing (nothing is checked for it)."""
    out = []
    for n, frf in sorted(job.frf.items()):
        for d, direction in (("x", frf.x), ("y", frf.y)):
            out += [f"warning: T{n}'s tip FRF ([tools.{n}.frf]) in {d}: {doubt}" for doubt in direction.doubts]
        if not (cut.checked & (cut.tool == n)).any():
            out.append(f"note: T{n} has a tip FRF ([tools.{n}.frf]) but cuts nothing in this program: "
                       "no chatter is checked for it")
    return tuple(out)
