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


HEADER = "f_hz,re_x_mm_per_N,im_x_mm_per_N,re_y_mm_per_N,im_y_mm_per_N\n"


def mode_csv(path: Path, f_hz, scale: float = 1.0, sign: float = 1.0) -> None:
    """A measured-FRF CSV of the chatter_slot mode (2200 Hz, ζ 0.03, 8000 N/mm: the closed form
    1/(k(1 − r² + 2iζr))) sampled at f_hz in X and Y, times `scale`, X's imaginary part times `sign`."""
    rows = []
    for f in f_hz:
        g = scale / (8000 * (1 - (f / 2200) ** 2 + 2j * 0.03 * f / 2200))
        rows.append(f"{f:g},{g.real:.9e},{sign * g.imag:.9e},{g.real:.9e},{g.imag:.9e}\n")
    path.write_text(HEADER + "".join(rows))
