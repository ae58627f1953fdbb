"""`millpost tap fit|chatter`: the tool tip's modes from a hammer test, and the chatter frequency and the
stable spindle speeds from a recording of a chattering cut."""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from ..errors import ConfigError
from ..files import json_text, write_atomic
from ..safety import check_outputs
from ..stability.tap import ModalFit, analyse_chatter, read_recording, read_tap_log

EXAMPLE_FIT = "millpost tap fit tap-x.csv tap-y.csv --tool 1 --json modes.json --toml frf.toml"
EXAMPLE_CHATTER = "millpost tap chatter cut.csv --rpm 9000 --flutes 3 --spindle-max 15000"

HELP_FIT = """\
LOG: CSV with t_s (s, evenly spaced), force_N (hammer force, N) and the response at the tool tip in the
hammer's direction: accel_m_s2 (m/s²), vel_mm_s (mm/s) or disp_mm (mm); tap several times (5 to 10 hits,
each left to ring down before the next). One log is the direction --direction; two logs are X, then Y.
Prints each direction's modes: natural frequency fn_hz (Hz), damping ratio zeta, modal stiffness
k_N_per_mm (N/mm), and the fit's R² and mean coherence. --toml writes the modes as a job's [tools.N.frf]
table, x = [...] and y = [...] (without a Y log the job takes y = x; docs/tap-test.md)."""

HELP_CHATTER = """\
REC: CSV with t_s (s, evenly spaced) and signal (a microphone or an accelerometer near the cut; any unit),
optionally spindle_rpm. Says whether the cut chatters: the strongest peak that is not a spindle or
tooth-passing harmonic must stand above the noise floor by more than noise passes 1 time in 100, or
(an even flute count: period-doubling chatter at (k + 1/2)·f_tooth is a spindle harmonic) such a harmonic
must stand 20 dB above its neighbouring runout harmonics (docs/tap-test.md). If so, prints the chatter frequency f_c, the lobe number and phase ε at this speed
(f_c/f_tooth = lobe + ε/2π), and the fastest stable speeds n_j = 60·f_c/(flutes·j) within the spindle's
range (Tlusty's rule: the tooth-passing frequency on f_c or a fraction of it). Chatter at the new speed
moves near the mode again: a second recording there refines it."""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("tap", help="modes from a hammer test; chatter frequency and stable speeds from a recording",
                       description=__doc__, epilog=f"example:\n  {EXAMPLE_FIT}\n  {EXAMPLE_CHATTER}",
                       formatter_class=argparse.RawDescriptionHelpFormatter)
    s = p.add_subparsers(dest="tap_command", required=True, metavar="fit|chatter")
    fit = s.add_parser("fit", help="fit the tool tip's modes to a hammer-test log", description=HELP_FIT,
                       epilog=f"example:\n  {EXAMPLE_FIT}", formatter_class=argparse.RawDescriptionHelpFormatter)
    fit.add_argument("logs", nargs="+", metavar="LOG", help="tap log (CSV); two logs: the X test, then the Y test")
    fit.add_argument("--direction", choices=("x", "y"), help="machine direction of a single log's test (default x)")
    fit.add_argument("--tool", type=int, default=1, metavar="N", help="tool number for --toml (default 1)")
    fit.add_argument("--modes", type=int, metavar="N", help="number of modes (default: chosen by the fit, "
                     "docs/tap-test.md)")
    fit.add_argument("--band", metavar="LO,HI", help="frequencies to fit (Hz; default: the band the hammer excites)")
    fit.add_argument("--window", type=float, metavar="S", help="exponential window time constant τ (s; default "
                                                                "chosen from the slowest decay)")
    fit.add_argument("--json", metavar="OUT", help="write the modes and the fit's quality as JSON ('-' for stdout)")
    fit.add_argument("--toml", metavar="OUT", help="write the modes as a job's [tools.N.frf] table")
    fit.set_defaults(func=run_fit)

    ch = s.add_parser("chatter", help="chatter frequency and stable speeds from a recording of a cut",
                      description=HELP_CHATTER, epilog=f"example:\n  {EXAMPLE_CHATTER}",
                      formatter_class=argparse.RawDescriptionHelpFormatter)
    ch.add_argument("recording", help="recording (CSV)")
    ch.add_argument("--rpm", type=float, metavar="RPM", help="spindle speed of the cut (default: the mean of the "
                                                             "spindle_rpm column)")
    ch.add_argument("--flutes", type=int, required=True, metavar="Z", help="number of flutes")
    ch.add_argument("--spindle-min", type=float, default=0.0, metavar="RPM", help="slowest spindle speed (rpm)")
    ch.add_argument("--spindle-max", type=float, default=math.inf, metavar="RPM", help="fastest spindle speed (rpm)")
    ch.add_argument("--speeds", type=int, default=5, metavar="N", help="how many stable speeds to list (default 5)")
    ch.add_argument("--json", metavar="OUT", help="write the result as JSON ('-' for stdout)")
    ch.set_defaults(func=run_chatter)


def _band(text: str | None) -> tuple[float, float] | None:
    if text is None:
        return None
    try:
        lo, hi = (float(v) for v in text.split(","))
    except ValueError:
        raise ConfigError("--band", text, "two frequencies LO,HI (Hz)") from None
    if not 0 <= lo < hi:
        raise ConfigError("--band", text, "0 ≤ LO < HI (Hz)")
    return lo, hi


def frf_toml(tool: int, fits: dict[str, tuple[str, tuple]]) -> str:
    """The job's [tools.N.frf] table: per direction (x, y) the modes as inline tables; `fits` maps the
    direction to (its log's name, its modes)."""
    source = ", ".join(f"{log} ({d})" for d, (log, _) in fits.items())
    lines = [f"# fitted by millpost tap fit from {source}", f"[tools.{tool}.frf]"]
    for d, (_, modes) in fits.items():
        rows = ", ".join(f"{{fn_hz = {m.fn_hz:.6g}, zeta = {m.zeta:.4g}, k_N_per_mm = {m.k_N_per_mm:.6g}}}"
                         for m in modes)
        lines.append(f"{d} = [{rows}]")
    return "\n".join(lines) + "\n"


def _directions(args: argparse.Namespace) -> dict[str, str]:
    """The log of each direction: one log is --direction's (default x), two are x and y."""
    if len(args.logs) > 2:
        raise ConfigError("LOG", " ".join(args.logs), "one tap log, or two: the X test and the Y test")
    if len(args.logs) == 2:
        if args.direction:
            raise ConfigError("--direction", args.direction, "no --direction with two logs (they are X, then Y)")
        return dict(zip("xy", args.logs))
    direction = args.direction or "x"
    if args.toml and direction == "y":
        raise ConfigError("--toml", args.toml, "the X log too (a job's [tools.N.frf] needs x; y defaults to x)")
    return {direction: args.logs[0]}


def run_fit(args: argparse.Namespace) -> int:
    check_outputs({"--json": args.json, "--toml": args.toml}, args.logs)
    results, fits = {}, {}
    for d, log in _directions(args).items():
        fit = ModalFit(args.modes, band_hz=_band(args.band), window_s=args.window).fit(read_tap_log(log))
        hits = fit.measured_.hits
        results[d] = {"log": log, "modes": [{"fn_hz": m.fn_hz, "zeta": m.zeta, "k_N_per_mm": m.k_N_per_mm}
                                            for m in fit.modes_],
                      "r2": fit.r2_, "coherence": fit.coherence_, "hits": len(hits.starts),
                      "window_tau_s": fit.measured_.tau_s, "fit_band_hz": list(fit.fit_band_hz_),
                      "residual": {"upper_mm_per_N": fit.residual_[0], "lower_mm_Hz2_per_N": fit.residual_[1]},
                      "notes": fit.notes_}
        fits[d] = (log, fit.modes_)
        if args.json != "-":
            for i, m in enumerate(fit.modes_, 1):
                print(f"{d} mode {i}: fn {m.fn_hz:.1f} Hz, zeta {m.zeta:.4f}, k {m.k_N_per_mm:.4g} N/mm")
            print(f"{d} fit: R² {fit.r2_:.4f}, coherence {fit.coherence_:.3f}, {len(hits.starts)} hits, "
                  f"{fit.fit_band_hz_[0]:.0f}–{fit.fit_band_hz_[1]:.0f} Hz")
        for note in fit.notes_:
            print(f"millpost: note: {d}: {note}", file=sys.stderr)
    _write_json(args.json, results, "tap fit")
    if args.toml:
        write_atomic(args.toml, frf_toml(args.tool, fits))
        print(f"millpost: wrote {args.toml}", file=sys.stderr)
    return 0


def run_chatter(args: argparse.Namespace) -> int:
    check_outputs({"--json": args.json}, [args.recording])
    rec = read_recording(args.recording)
    rpm = args.rpm
    if rpm is None:
        logged = rec.columns.get("spindle_rpm", np.array([np.nan]))
        if not np.isfinite(logged).any():
            raise ConfigError("--rpm", None, "give the spindle speed, or a spindle_rpm column in the recording")
        rpm = float(np.nanmean(logged))
    c = analyse_chatter(rec, rpm, args.flutes, rpm_min=args.spindle_min, rpm_max=args.spindle_max, count=args.speeds)
    result = {"chatter": c.chatter, "f_chatter_hz": c.f_chatter_hz, "peak_to_floor": c.peak_to_floor,
              "threshold": c.threshold, "rpm": c.rpm, "flutes": c.flutes, "f_tooth_hz": c.f_tooth_hz,
              "lobe": c.lobe, "epsilon_rad": c.epsilon_rad, "speeds": [{"j": j, "rpm": n} for j, n in c.speeds],
              "period_doubling": c.period_doubling, "notes": c.notes}
    if args.json != "-":
        above = (f"{10 * math.log10(c.peak_to_floor):.1f} dB above the neighbouring spindle harmonics: "
                 "period doubling" if c.period_doubling else
                 f"{10 * math.log10(c.peak_to_floor):.1f} dB above the noise floor")
        if not c.chatter:
            print(f"no chatter found: the strongest non-harmonic peak, {c.f_chatter_hz:.1f} Hz, is {above}, under "
                  f"the {10 * math.log10(c.threshold):.1f} dB that noise passes 1 time in 100")
        else:
            print(f"chatter: {c.f_chatter_hz:.1f} Hz ({above}), tooth passing {c.f_tooth_hz:.1f} Hz at "
                  f"{c.rpm:.0f} rpm: lobe {c.lobe}, epsilon {c.epsilon_rad:.2f} rad")
            for j, n in c.speeds:
                print(f"stable speed j={j}: {n:.0f} rpm")
            if not c.speeds:
                print("stable speed: none within the spindle's range")
    for note in c.notes:
        print(f"millpost: note: {note}", file=sys.stderr)
    _write_json(args.json, result, "tap chatter")
    return 0


def _write_json(path: str | None, result: dict, what: str) -> None:
    if path == "-":
        print(json_text(result, what))
    elif path:
        write_atomic(path, json_text(result, what) + "\n")
        print(f"millpost: wrote {path}", file=sys.stderr)
