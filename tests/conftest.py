"""Shared test fixtures: where the real third-party material lives (../shared/data)."""

from __future__ import annotations

from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_data(*parts: str) -> Path:
    """A path under ../shared/data, or skip the test with a clear reason when it is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is absent (../shared/data holds third-party material, not in the repo)")
    return path


@pytest.fixture(scope="session")
def slotting_result():
    """The slotting sample job optimized once per session: (job, Result)."""
    from millpost.job import load_job
    from millpost.optimize import optimize
    job = load_job(Path(__file__).resolve().parents[1] / "sample_jobs" / "slotting")
    return job, optimize(job, progress=False, trace=True)
