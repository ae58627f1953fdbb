"""Plug-ins that plug in: a third-party package, built here as a real wheel and installed by pip into a
folder of its own, registers a force model (``millpost.force_models``) and a controller dialect
(``millpost.dialects``) through entry points only; a fresh millpost process with that folder on its path
uses both, and one without it refuses their names."""

from __future__ import annotations

import base64
import hashlib
import json
import os
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

PLUGIN = '''\
"""A demo millpost plug-in: a dull-tool force model and a controller dialect."""
from millpost.forces import Mechanistic
from millpost.gcode.dialects import Dialect


class DoubledMechanistic(Mechanistic):
    """The material's mechanistic coefficients, every one doubled (a worn edge)."""

    name = "doubled"

    @classmethod
    def from_material(cls, material, **settings):
        return cls.from_coefficients(*(2 * Mechanistic.from_material(material).coef_), **settings)


DEMO = Dialect("democnc", trailing_point=True, end_code="M30", markers=(r"democnc",))
'''
ENTRY_POINTS = """\
[millpost.dialects]
democnc = millpost_demo_plugin:DEMO

[millpost.force_models]
doubled = millpost_demo_plugin:DoubledMechanistic
"""


def _wheel(folder: Path) -> Path:
    """A pure-Python wheel (PEP 427) holding the demo package and its entry points."""
    info = "millpost_demo_plugin-0.1.dist-info"
    files = {"millpost_demo_plugin/__init__.py": PLUGIN,
             f"{info}/METADATA": "Metadata-Version: 2.1\nName: millpost-demo-plugin\nVersion: 0.1\n",
             f"{info}/WHEEL": "Wheel-Version: 1.0\nGenerator: millpost-tests\nRoot-Is-Purelib: true\nTag: py3-none-any\n",
             f"{info}/entry_points.txt": ENTRY_POINTS}
    record = []
    for name, text in files.items():
        digest = base64.urlsafe_b64encode(hashlib.sha256(text.encode()).digest()).rstrip(b"=").decode()
        record.append(f"{name},sha256={digest},{len(text.encode())}")
    record.append(f"{info}/RECORD,,")
    path = folder / "millpost_demo_plugin-0.1-py3-none-any.whl"
    with zipfile.ZipFile(path, "w") as zf:
        for name, text in files.items():
            zf.writestr(name, text)
        zf.writestr(f"{info}/RECORD", "\n".join(record) + "\n")
    return path


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plugin")
    target = tmp / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-index", "--target",
                    str(target), str(_wheel(tmp))], check=True)
    assert (target / "millpost_demo_plugin-0.1.dist-info" / "entry_points.txt").exists()
    return target


def _millpost(args: list[str], site: Path | None) -> subprocess.CompletedProcess:
    path = [str(site)] if site else []
    env = {**os.environ, "PYTHONPATH": os.pathsep.join(path + [str(ROOT / "src")])}
    return subprocess.run([sys.executable, "-m", "millpost.cli", *args], env=env, capture_output=True, text=True)


CALC = ["calc", "--diameter", "6", "--flutes", "3", "--material", "al6061", "--ae", "3", "--ap", "3",
        "--rpm", "10000", "--fz", "0.05", "--json"]


def test_force_model_plugin_is_used(site, tmp_path):
    base = _millpost([*CALC, "--model", "mechanistic"], site)
    dull = _millpost([*CALC, "--model", "doubled"], site)
    assert base.returncode == 0 and dull.returncode == 0, dull.stderr
    f0, f1 = json.loads(base.stdout), json.loads(dull.stdout)
    # the mechanistic law is linear in its coefficients: every force and the power double exactly
    for a, b in zip(f0["F_avg_N"], f1["F_avg_N"]):
        assert b == pytest.approx(2 * a, rel=1e-9, abs=1e-9)
    assert f1["power_W"] == pytest.approx(2 * f0["power_W"], rel=1e-9)
    # a job may name it
    job = tmp_path / "job"
    job.mkdir()
    text = (ROOT / "sample_jobs" / "slotting" / "job.toml").read_text()
    (job / "job.toml").write_text(text.replace('program = "program.nc"',
                                               f'program = "{ROOT / "sample_jobs" / "slotting" / "program.nc"}"')
                                  + '\n[limits]\nmodel = "doubled"\n' if "[limits]" not in text else text)
    check = subprocess.run([sys.executable, "-c", "import sys; from millpost.job import load_job; "
                            "j = load_job(sys.argv[1]); print(type(j.material.force_model(j.settings.model)).__name__)",
                            str(job)], env={**os.environ, "PYTHONPATH": f"{site}{os.pathsep}{ROOT / 'src'}"},
                           capture_output=True, text=True)
    assert check.returncode == 0 and check.stdout.strip() == "DoubledMechanistic", check.stderr
    without = _millpost([*CALC, "--model", "doubled"], None)
    assert without.returncode == 2 and "invalid choice" in without.stderr


def test_dialect_plugin_is_used(site, tmp_path):
    out = tmp_path / "demo.nc"
    program = ROOT / "sample_jobs" / "slotting" / "program.nc"
    done = _millpost(["convert", str(program), "--to", "democnc", "-o", str(out)], site)
    assert done.returncode == 0, done.stderr
    text = out.read_text()
    assert "M30" in text and "X-2." in text  # the plug-in's end code and trailing points
    marked = tmp_path / "marked.nc"
    marked.write_text("(post: democnc)\nG21 G90\nG0 X1 Y2\nG1 X5 F300\nM30\n")
    summary = _millpost(["inspect", str(marked)], site)
    assert json.loads(summary.stdout)["dialect"] == "democnc"
    refused = _millpost(["convert", str(program), "--to", "democnc", "-o", str(tmp_path / "x.nc")], None)
    assert refused.returncode != 0 and "democnc" in refused.stderr
