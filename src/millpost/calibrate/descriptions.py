"""The description files calibrate and discover write: a job's material or machine reference, and a
machine description with fitted values (the material's is `coefficients.material_dict`)."""

from __future__ import annotations

from pathlib import Path

from ..config import load_description, load_toml
from ..job import load_job
from ..machine import Machine


def job_ref(target: str, key: str) -> str:
    """The material or machine a job (plan folder or job file) names: a built-in name, or a path relative
    to the job."""
    path = load_job(target).path
    value = str(load_toml(path)[key])
    return str(path.parent / value) if value.endswith(".toml") and not Path(value).is_absolute() else value


def machine_dict(base: str, updates: dict, provenance: str) -> dict:
    """The machine `base` with `updates` (section → fields; axes → axis → fields), its source naming
    `provenance`; refused when optimize would not read it."""
    data, _ = load_description("machines", base)
    for section, values in updates.items():
        if section == "axes":
            for axis, fields in values.items():
                data["axes"][axis].update({k: float(v) for k, v in fields.items()})
        else:
            data[section].update({k: list(v) if isinstance(v, tuple) else float(v) for k, v in values.items()})
    data["source"] = f"{data.get('source', '')}; {provenance}: " + ", ".join(
        f"{s}.{k}" for s, v in updates.items() for k in (v if s != "axes" else
                                                         [f"{a}.{f}" for a, fs in v.items() for f in fs]))
    Machine.from_dict(data)
    return data
