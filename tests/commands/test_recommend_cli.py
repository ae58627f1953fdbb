"""`millpost recommend` on the command line: JSON keys, CAM dialog formats, sweep and plot, refusals."""

from __future__ import annotations

import json

import pytest

from millpost.cli import main


def test_recommend_cli(capsys, tmp_path):
    base = ["recommend", "--diameter", "6", "--flutes", "3", "--flute-length", "18", "--stickout", "25",
            "--material", "al6061", "--machine", "hobby-router", "--rpm", "20000", "--ap", "6"]
    assert main([*base, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("ap_mm", "ae_mm", "rpm", "fz_mm", "feed_mm_min", "mrr_mm3_min", "deflection_mm", "power_W", "binding"):
        assert key in out
    assert out["rpm"] == 20000 and out["ap_mm"] == 6
    assert main([*base, "--format", "freecad", "--json"]) == 0
    fc = json.loads(capsys.readouterr().out)
    assert fc["Step over"] == pytest.approx(100 * out["ae_mm"] / 6) and fc["Horizontal feed"] == out["feed_mm_min"]
    assert main([*base, "--format", "fusion"]) == 0
    assert "Optimal load" in capsys.readouterr().out
    png = tmp_path / "sweep.png"
    assert main([*base[:-4], "--sweep", "--plot", str(png)]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    assert lines[0].startswith("ap_mm,ae_mm,rpm") and len(lines) > 10
    assert png.stat().st_size > 1000
    assert main([*base, "--max-deflection", "1e-7"]) == 2
    assert "relax a limit" in capsys.readouterr().err
    assert main([*base[:-2], "--ap", "40"]) == 2
    assert "outside" in capsys.readouterr().err
