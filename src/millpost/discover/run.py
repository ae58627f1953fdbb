"""The discover workflow: align a measured log to the job's forward model, refit the base model on the
fitting blocks, select effects on the held-out blocks (`search.select`), and say what changed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..job import Job
from ..measure import Alignment, Log, align
from ..signals import Signals, simulate
from .effects.base import Effect
from .rows import Rows, from_log
from .search import Selection, candidates, held_out_rms, select


@dataclass
class Discovery:
    """What discover found: the alignment, the rows used, the selection and notes."""

    alignment: Alignment
    rows: Rows
    selection: Selection
    nominal_coef: dict[str, float]
    notes: list[str]
    log_rows: int
    rows_source: str = "<log>"

    @property
    def effects(self) -> list[Effect]:
        return self.selection.effects

    def rms(self, after: bool) -> dict[str, float]:
        s = self.selection
        return held_out_rms(self.rows, s.predict_after() if after else s.predict_before(), s.block >= 0)

    def summary(self) -> dict:
        """The JSON result: effects with their parameters, standard errors, channels and held-out RMS before
        and after each; held-out RMS per channel of the refitted base (before) and the final model (after)."""
        s = self.selection
        held = s.block >= 0
        effects = []
        for e, (before, after) in zip(s.effects, s.steps):
            rb = held_out_rms(self.rows, {c: before[c] for c in e.channels_}, held)
            ra = held_out_rms(self.rows, {c: after[c] for c in e.channels_}, held)
            rivals = [a["effects"][1] for a in s.ambiguous if a["effects"][0] == e.name]
            effects.append({"name": e.name, "params": _clean(e.params_), "stderr": _clean(e.stderr_),
                            "channels": e.channels_, "rms_before": _clean(rb), "rms_after": _clean(ra),
                            "meaning": e.meaning, "ambiguous_with": rivals})
        return {"effects": effects, "ambiguous": s.ambiguous, "rms_before": _clean(self.rms(False)),
                "rms_after": _clean(self.rms(True)), "offset_s": round(self.alignment.offset_s, 6),
                "alignment": self.alignment.method, "notes": self.notes}

    def predictions(self) -> dict[str, np.ndarray]:
        """One row per log row: t_s, held_out (1 on the held-out rows the JSON's RMS are taken on) and per
        measured channel <ch>_measured, <ch>_before, <ch>_after (nan where the row falls outside the
        program)."""
        n = self.log_rows
        s = self.selection
        before, after = s.predict_before(), s.predict_after()
        out = {"t_s": np.full(n, np.nan), "held_out": np.zeros(n)}
        out["t_s"][self.rows.index] = self.rows.t_s
        out["held_out"][self.rows.index] = s.block >= 0
        for c in self.rows.channels:
            for kind, v in (("measured", self.rows.measured[c]), ("before", before[c]), ("after", after[c])):
                col = np.full(n, np.nan)
                col[self.rows.index] = v
                out[f"{c}_{kind}"] = col
        return out


def _clean(d: dict) -> dict:
    return {k: (None if not np.isfinite(v) else float(f"{v:.6g}")) for k, v in d.items()}


def discover(job: Job, log: Log, *, signals: Signals | None = None, effects: list[str] | None = None,
             max_effects: int = 2) -> Discovery:
    """Align `log` to `job` and search the candidate effects (all registered, or `effects`)."""
    signals = signals if signals is not None else simulate(job)
    alignment = align(log, signals)
    rows = from_log(log, alignment, signals, job)
    nominal = job.material.force_model("mechanistic").coefficients
    sel = select(rows, nominal, candidates(effects), max_effects=max_effects)
    how = (f"correlation {alignment.correlation:.3f}" if alignment.method == "xcorr" else
           f"position RMS {alignment.position_rms_mm:.3f} mm")
    notes = [f"aligned by {alignment.method} ({how}); "
             f"{len(rows)} of {len(log)} log rows inside the program; {int((sel.block >= 0).sum())} held out "
             f"in {int(sel.block.max()) + 1} time blocks"]
    if rows.use is not None and not rows.use.all():
        notes.append(f"{int((~rows.use).sum())} rows where the tool enters or leaves the material are left out of "
                     "fits and scores (the first look-ahead of a cut, whose engagement is not sampled; within a "
                     "tool radius of its end, where the engagement's single arc per slice overstates the force)")
    refit = {k: v for k, v in sel.base.params().items() if k in nominal}
    if refit:
        change = ", ".join(f"{k} {nominal[k]:.4g} → {v:.4g}" for k, v in refit.items())
        nominal_rms = ", ".join(f"{c} {alignment.residual_rms[c]:.4g}" for c in rows.channels
                                if c in alignment.residual_rms)
        notes.append(f"coefficients: the base refit moved the cutting coefficients ({change}); RMS with the "
                     f"job's nominal coefficients (whole log): {nominal_rms}")
    for k, rs in enumerate(sel.scores):
        ranked = sorted(((n, r) for n, r in rs.items() if r.get("applicable")), key=lambda x: -x[1]["gain"])
        notes.append(f"round {k + 1}: " + "; ".join(f"{n} gain {100 * r['gain']:.1f} % p {r['p']:.2g}"
                                                     + ("" if r["physical"] else " (unphysical sign)")
                                                     + "".join(f" (worsens {c} by {100 * w:.0f} %)"
                                                               for c, w in r["worsens"].items())
                                                     for n, r in ranked[:5])
                     + "".join(f"; {n} not applicable" + (f" ({r['reason']})" if r.get("reason") else "")
                               for n, r in rs.items() if not r.get("applicable")))
    for a in sel.ambiguous:
        first, second = a["effects"]
        notes.append(f"ambiguous: {first} or {second}: both explain the held-out gap; on the {a['blocks']} held-out "
                     f"blocks where they differ most, {first} fits better in {100 * a['better']:.0f} % (Wilcoxon "
                     f"p {a['p']:.2g}): the log cannot tell them apart (cut a part where they disagree: air "
                     "moves, a load that falls with time)")
    if not sel.effects:
        notes.append("no effect is significant: the refitted base model explains the held-out data")
    return Discovery(alignment, rows, sel, nominal, notes, len(log), log.path)
