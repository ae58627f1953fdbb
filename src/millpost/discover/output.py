"""What discover writes besides its JSON: the updated model files (`write_model`) with the named effects'
terms where `optimize` uses them:

- cutting coefficients: the refitted mechanistic set into a material file; with tool_wear, at the wear
  state of the log's end (K·(1 + w·L_end): a worn tool cuts with higher forces from now on);
- axis_friction: Coulomb and viscous friction (N, N·s/mm) into the machine's axes, through each axis's
  K_t, transmission and efficiency (friction eats drive current, so less is left for cutting);
- spindle_no_load: the machine's no-load power curve raised by c₁n + c₂n²;
- deflection: the fitted compliance as the machine's X and Y stiffness (1/C; a deflection limit then
  holds the feed where the tool would bend too far).
A job.toml beside them points at the new files (program and stock as the original job's).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..calibrate.machine_fit import AxisDrive
from ..calibrate.descriptions import job_ref, machine_dict
from ..config import dump_toml, load_description, load_toml
from ..files import write_atomic
from ..materials import Material
from .run import Discovery

MECH_FIELDS = {"Ktc": "Ktc_N_mm2", "Krc": "Krc_N_mm2", "Kac": "Kac_N_mm2", "Kte": "Kte_N_per_mm",
               "Kre": "Kre_N_per_mm", "Kae": "Kae_N_per_mm"}


def write_model(d: Discovery, job_path: str | Path, out: str | Path) -> list[Path]:
    """Write material.toml, machine.toml and job.toml into folder `out`; returns the paths written."""
    job_path = Path(job_path)
    job_path = job_path / "job.toml" if job_path.is_dir() else job_path
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    final = d.effects[-1].fit_ if d.effects else d.selection.base
    p = final.params()
    effects = {e.name: e for e in d.effects}
    factor = 1.0
    if "tool_wear" in effects:
        factor = 1.0 + effects["tool_wear"].params_["wear_per_m"] * float(d.rows.features["cut_length_m"].max())
    material, _ = load_description("materials", job_ref(str(job_path), "material"))
    mech = material.setdefault("mechanistic", {})
    for k, field in MECH_FIELDS.items():
        value = p.get(k, d.nominal_coef[k]) * factor
        mech[field] = round(max(float(value), 0.0), 4)
    mech["source"] = f"millpost discover on {d.rows_source}: refitted" + (
        f", at the tool wear of the log's end (×{factor:.3f})" if factor != 1.0 else "")
    material["name"] = f"{material['name']}-discovered"
    Material.from_dict(material)
    written = []
    mat_path = out / "material.toml"
    write_atomic(mat_path, dump_toml(material))
    written.append(mat_path)
    machine_ref = job_ref(str(job_path), "machine")
    updates: dict = {}
    from ..machine import Machine
    machine = Machine.load(machine_ref)
    if "axis_friction" in effects:
        e = effects["axis_friction"]
        for axis in "xyz":
            if f"coulomb_{axis}_A" in e.params_:
                drive = AxisDrive(("coulomb", "viscous"))
                drive.coef_ = np.array([e.params_[f"coulomb_{axis}_A"], e.params_[f"viscous_{axis}_A_per_mm_s"]])
                drive.intercept_ = 0.0
                updates.setdefault("axes", {})[axis] = {k: max(v, 0.0) for k, v in
                                                         drive.axis_constants(machine.axes[axis]).items()}
    if "spindle_no_load" in effects:
        e = effects["spindle_no_load"]
        sp = machine.spindle
        rpm = np.linspace(max(sp.rpm_min, 1.0), sp.rpm_max, 8)
        n = rpm / 1000.0
        idle = sp.idle_power_at_W(rpm) + e.params_["c1_W_per_krpm"] * n + e.params_["c2_W_per_krpm2"] * n * n
        updates["spindle"] = {"idle_rpm": tuple(float(r) for r in rpm),
                              "idle_power_W": tuple(float(max(w, 0.0)) for w in idle)}
    if "deflection" in effects:
        c = effects["deflection"].params_["compliance_mm_per_N"]
        if c > 0:
            for axis in "xy":
                updates.setdefault("axes", {}).setdefault(axis, {})["stiffness_N_per_mm"] = 1.0 / c
    mach_path = out / "machine.toml"
    write_atomic(mach_path, dump_toml(machine_dict(machine_ref, updates, "millpost discover")))
    written.append(mach_path)
    job = load_toml(job_path)
    job["program"] = str((job_path.parent / job["program"]).resolve())
    job["material"], job["machine"] = "material.toml", "machine.toml"
    stock = job.get("stock", {})
    if isinstance(stock.get("file"), str):
        stock["file"] = str((job_path.parent / stock["file"]).resolve())
    job_out = out / "job.toml"
    write_atomic(job_out, dump_toml(job))
    written.append(job_out)
    return written
