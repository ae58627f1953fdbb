"""`millpost discover JOB --log LOG.csv --json OUT.json`: find where the simulation and a measured log
disagree, name the missing effect, refit with it, and show the gap shrink."""

from __future__ import annotations

import argparse
import json
import sys

HELP = """\
The log (measurement log format: t_s and any of fx_N, fy_N, fz_N, spindle_power_W, spindle_current_A,
ix_A, iy_A, iz_A; positions help the alignment) is aligned to the job's forward model and split into time
blocks: two of three fit, one is held out. The base model (cutting coefficients, offsets, axis inertia)
is refitted first: a gap that refit closes is reported as coefficients in the notes. Then every
registered effect is fitted with it and kept when the held-out error falls significantly (held-out F-test
on 0.5 s residual means, Bonferroni over the candidates), by at least 25 % on the channels it acts on, and with
physical signs (wear, compliance, mass, lag, exponent > 0); a second effect is
searched the same way. JSON: effects (name, params, stderr, channels, rms_before, rms_after), held-out
rms_before/rms_after per channel, offset_s, notes.

example:
  millpost discover job.toml --log run.csv --json found.json --predictions pred.csv --report found.html"""


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("discover", help="name the effect a measured log shows that the model lacks",
                       description=__doc__, epilog=HELP, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("job", metavar="JOB", help="job folder or job.toml (the program the log recorded)")
    p.add_argument("--log", required=True, metavar="LOG.csv", help="measurement log (CSV or NPZ)")
    p.add_argument("--json", required=True, metavar="OUT.json", help="result ('-' for stdout)")
    p.add_argument("--predictions", metavar="PRED.csv", help="per log row: t_s, held_out (1: scored), <ch>_measured, _before, _after")
    p.add_argument("--report", metavar="OUT.html", help="residual plots before/after (one HTML file)")
    p.add_argument("--write-model", metavar="DIR", help="write material, machine and job files with the effects")
    p.add_argument("--effects", metavar="NAME,...", help="only these candidates (default: all registered)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:

    from ..discover.output import write_model
    from ..discover.run import discover
    from ..files import write_atomic, write_csv
    from ..job import load_job
    from ..measure import read_log

    job = load_job(args.job)
    log = read_log(args.log)
    d = discover(job, log, effects=args.effects.split(",") if args.effects else None)
    summary = d.summary()
    text = json.dumps(summary, indent=2, ensure_ascii=False) + "\n"
    if args.json == "-":
        sys.stdout.write(text)
    else:
        write_atomic(args.json, text)
    if args.predictions:
        write_csv(args.predictions, d.predictions())
    if args.report:
        from ..report.residuals import write_discover_report
        s = d.selection
        write_discover_report(args.report, str(args.log), summary, d.rows.t_s, d.rows.measured,
                              s.predict_before(), s.predict_after(), s.block >= 0)
    if args.write_model:
        for path in write_model(d, args.job, args.write_model):
            print(f"millpost: wrote {path}", file=sys.stderr)
    names = ", ".join(e["name"] if not e["ambiguous_with"] else "ambiguous: " + " or ".join(
        [e["name"]] + e["ambiguous_with"]) for e in summary["effects"]) or "none"
    shrink = {c: 1 - summary["rms_after"][c] / summary["rms_before"][c] for c in summary["rms_before"]
              if summary["rms_before"][c]}
    print(f"millpost discover: effects {names}; held-out RMS " + ", ".join(
        f"{c} {summary['rms_before'][c]:.4g} → {summary['rms_after'][c]:.4g} ({-100 * v:+.0f} %)"
        for c, v in shrink.items()), file=sys.stderr)
    return 0
