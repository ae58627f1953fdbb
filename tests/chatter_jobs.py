"""The chatter_slot sample job with its tool's FRF replaced: the chatter tests' jobs."""

from __future__ import annotations

from pathlib import Path

from millpost.job import Job, load_job

SLOT = Path(__file__).resolve().parents[1] / "sample_jobs" / "chatter_slot"


def job_with(folder: Path, frf_body: str) -> Job:
    """The chatter_slot job written to `folder` with the body of its [tools.1.frf] table replaced."""
    (folder / "program.nc").write_text((SLOT / "program.nc").read_text())
    toml = (SLOT / "job.toml").read_text()
    (folder / "job.toml").write_text(toml[:toml.index("[tools.1.frf]")] + "[tools.1.frf]\n" + frf_body + "\n")
    return load_job(folder)
