"""Many jobs at once on Dask: one job per task on a `dask.distributed` cluster (a local one with two
worker processes by default, or a running scheduler), each writing its program, summary and report
into a folder of its own; a job that fails is a row with its error, never the end of the batch. The
results table (CSV and HTML) has each job's status, cycle times, run time and links."""

from __future__ import annotations

import html
import logging
import time
import traceback
from collections.abc import Sequence
from pathlib import Path

from .files import json_text, write_atomic
from .progress import Progress, silent
from .summary import JobStatus

COLUMNS = ("job", "status", "cycle_time_before_s", "cycle_time_after_s", "cycle_time_baseline_s", "run_s",
           "output", "report", "message")


def run_one(job_path: str, out_dir: str) -> dict:
    """Optimize one job into `out_dir`: the program (the job's output file name), summary.json and
    report.html. Returns its row of the results table; errors become the row's status and message."""
    from .job import load_job
    from .optimize import optimize
    from .report import collect, write_report
    from .safety import check_outputs
    t0 = time.perf_counter()
    row = dict.fromkeys(COLUMNS, "")
    row["job"] = str(job_path)
    try:
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        job = load_job(job_path)
        output = out / job.output.name
        check_outputs({"output": output, "summary": out / "summary.json", "report": out / "report.html"},
                      job.inputs)
        result = optimize(job, progress=False, trace=True)  # the report plots the trace
        result.summary["output"] = str(output)
        summary = json_text(result.summary)
        write_atomic(output, result.text)
        write_atomic(out / "summary.json", summary + "\n")
        write_report(out / "report.html", collect(result.summary, result.trace, job))
        s = result.summary
        row.update(status=s["status"], output=str(output), report=str(out / "report.html"), message=s["message"],
                   **{k: s[k] for k in ("cycle_time_before_s", "cycle_time_after_s", "cycle_time_baseline_s")})
    except Exception as exc:  # noqa: BLE001 — one job's failure is its row, not the batch's end
        from .errors import MillpostError
        detail = str(exc) if isinstance(exc, (MillpostError, OSError)) else "".join(
            traceback.format_exception_only(type(exc), exc)).strip()
        row.update(status=JobStatus.ERROR, message=detail)
    row["run_s"] = round(time.perf_counter() - t0, 3)
    return row


def folder_names(jobs: Sequence[str]) -> list[str]:
    """One output folder name per job: the job folder's (or toml's) name, numbered when repeated."""
    names, seen = [], {}
    for j in jobs:
        p = Path(j)
        base = p.parent.name if p.suffix == ".toml" and p.name == "job.toml" else p.stem if p.suffix else p.name
        seen[base] = seen.get(base, 0) + 1
        names.append(base if seen[base] == 1 else f"{base}-{seen[base]}")
    return names


def run_batch(jobs: Sequence[str], out_dir: str | Path, *, scheduler: str | None = None, workers: int = 2,
              progress: Progress = silent) -> list[dict]:
    """Run every job as a Dask task (a LocalCluster of `workers` processes unless `scheduler` names a
    running one) and write results.csv and results.html into `out_dir`. Rows in the order given."""
    from dask.distributed import Client, LocalCluster, as_completed
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    names = folder_names(jobs)
    cluster = None if scheduler else LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                                   dashboard_address=None, silence_logs=logging.ERROR)
    rows: list[dict | None] = [None] * len(jobs)
    try:
        with Client(scheduler or cluster) as client:
            futures = {client.submit(run_one, str(Path(j).resolve()), str((out / n).resolve()), pure=False): k
                       for k, (j, n) in enumerate(zip(jobs, names))}
            progress("batch", 0, len(jobs))
            for done, future in enumerate(as_completed(futures), 1):
                k = futures[future]
                try:
                    rows[k] = future.result()
                except Exception as exc:  # noqa: BLE001 — a worker lost mid-job
                    rows[k] = {**dict.fromkeys(COLUMNS, ""), "job": str(jobs[k]), "status": JobStatus.ERROR,
                               "message": f"the task failed: {exc}"}
                progress("batch", done, len(jobs))
    finally:
        if cluster is not None:
            cluster.close()
    write_tables(rows, out)
    return rows


def write_tables(rows: list[dict], out: Path) -> None:
    """results.csv and results.html (report and program linked relative to the table)."""
    import csv
    import io
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    write_atomic(out / "results.csv", buf.getvalue())

    def cell(row: dict, key: str) -> str:
        value = row[key]
        if key in ("report", "output") and value:
            rel = Path(value).resolve().relative_to(out.resolve()).as_posix()
            return f'<a href="{html.escape(rel)}">{html.escape(Path(value).name)}</a>'
        return html.escape(f"{value:.1f}" if isinstance(value, float) else str(value))
    head = "".join(f"<th>{html.escape(c)}</th>" for c in COLUMNS)
    body = "".join("<tr>" + "".join(f"<td>{cell(r, c)}</td>" for c in COLUMNS) + "</tr>" for r in rows)
    ok = sum(r["status"] == JobStatus.SOLVED for r in rows)
    write_atomic(out / "results.html", f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
                 f"<title>millpost batch</title><style>td,th{{padding:0.2em 0.6em}}</style></head><body>"
                 f"<h1>millpost batch: {ok} of {len(rows)} jobs solved</h1><table><thead><tr>{head}</tr></thead>"
                 f"<tbody>{body}</tbody></table></body></html>\n")
