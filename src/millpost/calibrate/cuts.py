"""Cutting coefficients from steady cuts: the table format, its reader, and the fits.

A table of steady cuts is a CSV, one row per cut along +X beside a wall (ae ≥ D is a slot):

    diameter_mm,flutes,helix_deg,ae_mm,ap_mm,fz_mm,rpm[,climb][,fx_N,fy_N,fz_N][,spindle_power_W]

climb is 1 (down milling, default) or 0; fx_N, fy_N, fz_N are the mean force on the **tool** over whole
revolutions (the convention `millpost calc` prints: x along the feed, y to the left of it, z the tool
axis), spindle_power_W the mean cutting power (spindle power minus its no-load power at that speed).

The fits are the force models' own `fit` (millpost.forces): the mechanistic model by ordinary least
squares on the closed-form averages, which on a slot series at one depth is exactly the textbook
average-force method (per axis F̄ = F̄_c·f_z + F̄_e, then K_tc = 4F̄_yc/(N a), ...; Altintas ch. 2); the
Kienzle model in log space on |F̄_xy| and power. Uncertainties are standard errors from the fits'
covariances (HC3 sandwich for the mechanistic model, s²(JᵀJ)⁻¹ for Kienzle).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..engagement import Engagement
from ..errors import ParseError
from ..files import write_csv
from ..forces import COEF_NAMES, Kienzle, Measurements, Mechanistic, given_cut
from ..materials import Material
from ..measure.log import read_table
from ..tools.cutter import Tool

CUT_COLUMNS = {
    "diameter_mm": "tool diameter (mm)", "flutes": "number of flutes", "helix_deg": "helix angle (deg)",
    "ae_mm": "radial width of cut (mm)", "ap_mm": "axial depth of cut (mm)", "fz_mm": "feed per tooth (mm)",
    "rpm": "spindle speed (rpm)", "climb": "1 climb, 0 conventional",
    "fx_N": "mean force on the tool along the feed (N)", "fy_N": "mean force on the tool, left of the feed (N)",
    "fz_N": "mean force on the tool along its axis (N)", "spindle_power_W": "mean cutting power (W)",
}
REQUIRED = ("diameter_mm", "flutes", "helix_deg", "ae_mm", "ap_mm", "fz_mm", "rpm")


@dataclass
class Cuts:
    """Steady cuts (N rows). force_N: (N, 3) mean force on the tool, feed frame, nan where not measured;
    power_W: (N,) cutting power, nan where not measured. Lengths mm, speeds rpm."""

    diameter_mm: np.ndarray
    flutes: np.ndarray
    helix_deg: np.ndarray
    ae_mm: np.ndarray
    ap_mm: np.ndarray
    fz_mm: np.ndarray
    rpm: np.ndarray
    climb: np.ndarray
    force_N: np.ndarray
    power_W: np.ndarray
    source: str = "<cuts>"

    def __len__(self) -> int:
        return len(self.ae_mm)

    @property
    def has_force(self) -> bool:
        return bool(np.isfinite(self.force_N).any())

    @property
    def has_power(self) -> bool:
        return bool(np.isfinite(self.power_W).any())

    def tools(self) -> list[Tool]:
        return [Tool(diameter_mm=float(d), flutes=int(n), helix_deg=float(h))
                for d, n, h in zip(self.diameter_mm, self.flutes, self.helix_deg)]

    def engagement(self) -> Engagement:
        """Per row the engagement of a straight cut along +X (`given_cut`), in row order."""
        parts, order = [], []
        tools = self.tools()
        keys = sorted({(t.diameter_mm, t.flutes, t.helix_deg, int(c)) for t, c in zip(tools, self.climb)})
        for key in keys:
            idx = np.flatnonzero([(t.diameter_mm, t.flutes, t.helix_deg, int(c)) == key
                                  for t, c in zip(tools, self.climb)])
            parts.append(given_cut(tools[idx[0]], self.ae_mm[idx], self.ap_mm[idx], climb=bool(key[3]), slices=8))
            order.append(idx)
        eng = Engagement.concatenate(parts)
        return eng.select(np.argsort(np.concatenate(order)))

    def measurements(self) -> Measurements:
        return Measurements(fz_mm=self.fz_mm, rpm=self.rpm, force_N=self.force_N if self.has_force else None,
                            power_W=self.power_W if self.has_power else None)

    def write(self, path: str | os.PathLike) -> None:
        cols = {"diameter_mm": self.diameter_mm, "flutes": self.flutes, "helix_deg": self.helix_deg,
                "ae_mm": self.ae_mm, "ap_mm": self.ap_mm, "fz_mm": self.fz_mm, "rpm": self.rpm, "climb": self.climb,
                "fx_N": self.force_N[:, 0], "fy_N": self.force_N[:, 1], "fz_N": self.force_N[:, 2],
                "spindle_power_W": self.power_W}
        write_csv(path, cols, {"flutes": "%d", "climb": "%d", "fz_mm": "%.6g", "rpm": "%.6g"})


def read_cuts(path: str | os.PathLike) -> Cuts:
    """Read a table of steady cuts; errors name file:row:column and what was expected."""
    def check(name, *, file, line, column):
        if name not in CUT_COLUMNS:
            raise ParseError(f"unknown column {name!r}", file=file, line=line, column=column, word=name,
                             expected=f"one of {', '.join(CUT_COLUMNS)}")
    cols, header_at = read_table(path, check, required=REQUIRED, describe=CUT_COLUMNS)
    n = len(cols["ae_mm"])
    if n == 0:
        raise ParseError("no cuts in the table", file=str(path), line=header_at + 1, column=1,
                         expected="one row per cut")
    names = list(cols)
    for key, rule, ok in (("diameter_mm", "> 0", lambda v: v > 0), ("flutes", "a whole number >= 1",
                                                                      lambda v: (v >= 1) & (v == np.round(v))),
                          ("ae_mm", "> 0", lambda v: v > 0), ("ap_mm", "> 0", lambda v: v > 0),
                          ("fz_mm", "> 0", lambda v: v > 0), ("rpm", "> 0", lambda v: v > 0),
                          ("helix_deg", "in [0, 60]", lambda v: (v >= 0) & (v <= 60)),
                          ("climb", "1 or 0", lambda v: (v == 0) | (v == 1))):
        if key in cols:
            bad = np.flatnonzero(~ok(cols[key]))
            if len(bad):
                line, text = _row_line(path, header_at, bad[0])
                column = len(",".join(text.split(",")[:names.index(key)])) + (1 if names.index(key) == 0 else 2)
                raise ParseError(f"{key} must be {rule}", file=str(path), line=line, column=column,
                                 word=f"{cols[key][bad[0]]:g}", expected=rule)
    nan = np.full(n, np.nan)
    force = np.column_stack([cols.get(k, nan) for k in ("fx_N", "fy_N", "fz_N")])
    power = cols.get("spindle_power_W", nan)
    if not (np.isfinite(force).any() or np.isfinite(power).any()):
        raise ParseError("no measured forces or power", file=str(path), line=header_at, column=1,
                         expected="columns fx_N, fy_N, fz_N and/or spindle_power_W")
    return Cuts(cols["diameter_mm"], cols["flutes"].astype(int), cols["helix_deg"], cols["ae_mm"], cols["ap_mm"],
                cols["fz_mm"], cols["rpm"], cols.get("climb", np.ones(n)).astype(int), force, power, str(path))


def _row_line(path, header_at: int, row: int) -> tuple[int, str]:
    """(1-based line number, text) of data row `row` (0-based; comments and blank lines skipped)."""
    k = -1
    for lineno, raw in enumerate(Path(path).read_text().splitlines(), start=1):
        if lineno > header_at and raw.strip() and not raw.lstrip().startswith("#"):
            k += 1
            if k == row:
                return lineno, raw
    return header_at + row + 1, ""


@dataclass
class Fit:
    """Fitted models and residuals. residuals: {model: {"before"|"after": {"force_N": RMS, "power_W": RMS}}};
    before = the base material's coefficients (absent without a base)."""

    rows: int
    source: str
    mechanistic: Mechanistic | None
    kienzle: Kienzle | None
    residuals: dict[str, dict[str, dict[str, float]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict:
        out: dict = {"rows": self.rows, "source": self.source}
        if self.mechanistic is not None:
            se = np.sqrt(np.maximum(np.diag(self.mechanistic.coef_cov_), 0))
            out["mechanistic"] = {k: {"value": float(v), "stderr": float(s)}
                                  for k, v, s in zip(COEF_NAMES, self.mechanistic.coef_, se)}
            out["mechanistic_covariance"] = self.mechanistic.coef_cov_.tolist()
        if self.kienzle is not None:
            se = np.sqrt(np.maximum(np.diag(self.kienzle.coef_cov_), 0))
            out["kienzle"] = {k: {"value": float(v), "stderr": float(s)}
                              for k, v, s in zip(("kc11", "mc"), self.kienzle.coef_, se)}
            out["kienzle_covariance"] = self.kienzle.coef_cov_.tolist()
            out["kienzle_ratios"] = {"radial": self.kienzle.radial_ratio, "axial": self.kienzle.axial_ratio}
        after = self.residuals.get("mechanistic", {}).get("after", {})
        out["rms_N"] = after.get("force_N")
        out["rms_W"] = after.get("power_W")
        out["residuals"] = self.residuals
        out["notes"] = self.notes
        return out

    def table(self) -> str:
        """Coefficient, value, ±, and the residuals before and after, as text."""
        d = self.as_dict()
        lines = [f"{'coefficient':<12}{'value':>12}{'±':>10}"]
        units = {"Ktc": "N/mm²", "Krc": "N/mm²", "Kac": "N/mm²", "Kte": "N/mm", "Kre": "N/mm", "Kae": "N/mm",
                 "kc11": "N/mm²", "mc": ""}
        for model in ("mechanistic", "kienzle"):
            for k, v in d.get(model, {}).items():
                lines.append(f"{k:<12}{v['value']:>12.5g}{v['stderr']:>10.3g}  {units[k]}")
        for model, res in self.residuals.items():
            for which in ("force_N", "power_W"):
                b, a = res.get("before", {}).get(which), res.get("after", {}).get(which)
                if a is not None:
                    before = f"{b:.4g}" if b is not None else "-"
                    lines.append(f"residual RMS {model} {which}: before {before}, after {a:.4g}")
        return "\n".join(lines)


def fit_cuts(cuts: Cuts, base: Material | None = None) -> Fit:
    """Mechanistic and Kienzle coefficients from a table of steady cuts (see `fit_models`)."""
    return fit_models(cuts.engagement(), cuts.measurements(), cuts.tools(), base, cuts.source)


def fit_models(eng: Engagement, meas: Measurements, tools: list[Tool], base: Material | None = None,
               source: str = "") -> Fit:
    """Both force models fitted to measured means per sample (engagement, feed per tooth, speed, force on
    the tool in machine XYZ and/or cutting power). The base material gives the starting coefficients
    (needed when only power is measured: it fixes K_rc, K_ac, K_re, K_ae), the Kienzle force ratios, and
    the residuals before the fit."""
    fit = Fit(len(eng), source, None, None)
    if base is not None:
        mech = base.force_model("mechanistic", reweight_steps=0)
    else:
        mech = Mechanistic(reweight_steps=0)
    before_m = _residuals(mech, eng, meas, tools) if hasattr(mech, "coef_") else {}
    fit.mechanistic = mech.fit(eng, meas, tools)
    fit.residuals["mechanistic"] = {"before": before_m, "after": _residuals(fit.mechanistic, eng, meas, tools)}
    if meas.force_N is None:
        fit.notes.append("power only: K_tc and K_te are fitted; K_rc, K_ac, K_re, K_ae are the base material's")
    kz = base.force_model("kienzle") if base is not None else Kienzle()
    before_k = _residuals(kz, eng, meas, tools) if hasattr(kz, "coef_") else {}
    fit.kienzle = Kienzle(radial_ratio=kz.radial_ratio, axial_ratio=kz.axial_ratio).fit(eng, meas, tools)
    fit.residuals["kienzle"] = {"before": before_k, "after": _residuals(fit.kienzle, eng, meas, tools)}
    return fit


def _residuals(model, eng: Engagement, meas: Measurements, tools: list[Tool]) -> dict[str, float]:
    """RMS of measured − predicted: force components (N, machine XYZ) and power (W)."""
    n = len(eng)
    force, power = np.zeros((n, 3)), np.zeros(n)
    fz = np.broadcast_to(np.asarray(meas.fz_mm, float), (n,))
    rpm = np.broadcast_to(np.asarray(meas.rpm, float), (n,))
    groups: dict[Tool, list[int]] = {}
    for i, t in enumerate(tools):
        groups.setdefault(t, []).append(i)
    for t, idx in groups.items():
        loads = model.predict(eng.select(np.array(idx)), fz[idx], rpm[idx], t, peaks=False)
        force[idx], power[idx] = loads.force_N, loads.power_W
    out = {}
    if meas.force_N is not None:
        d = (np.asarray(meas.force_N) - force)[np.isfinite(meas.force_N)]
        out["force_N"] = float(np.sqrt(np.mean(d * d)))
    if meas.power_W is not None:
        d = (np.asarray(meas.power_W) - power)[np.isfinite(meas.power_W)]
        out["power_W"] = float(np.sqrt(np.mean(d * d)))
    return out


def material_dict(data: dict, fit: Fit, provenance: str) -> dict:
    """`data` (a material description) with the fitted [mechanistic] and [kienzle] tables."""
    data = dict(data)
    d = fit.as_dict()
    if fit.mechanistic is not None:
        k = fit.mechanistic.coef_
        rms = d.get("rms_N")
        data["mechanistic"] = {
            "Ktc_N_mm2": float(k[0]), "Krc_N_mm2": float(max(k[1], 0.0)), "Kac_N_mm2": float(k[2]),
            "Kte_N_per_mm": float(max(k[3], 0.0)), "Kre_N_per_mm": float(max(k[4], 0.0)), "Kae_N_per_mm": float(k[5]),
            "source": f"{provenance}; mechanistic fit, ± (1 s.e.) " + ", ".join(
                f"{n} {v['stderr']:.3g}" for n, v in d["mechanistic"].items()) +
            (f"; residual RMS {rms:.4g} N" if rms is not None else "") +
            (f"; {d['rms_W']:.4g} W" if d.get("rms_W") is not None else "")}
    if fit.kienzle is not None:
        kc, mc = fit.kienzle.coef_
        data["kienzle"] = {"kc11_N_mm2": float(kc), "mc": float(mc), "radial_ratio": fit.kienzle.radial_ratio,
                           "axial_ratio": fit.kienzle.axial_ratio,
                           "source": f"{provenance}; Kienzle fit, kc1.1 ± {d['kienzle']['kc11']['stderr']:.3g}, "
                                     f"mc ± {d['kienzle']['mc']['stderr']:.3g}; force ratios kept from the base"}
    return data
