"""The FreeCAD post in real FreeCAD: Debian's FreeCAD 0.20 headless (`freecadcmd`, apt `freecad`) builds
a Job with an Adaptive and a Pocket operation and posts it through FreeCAD's own post machinery
(`PostProcessor.load("millpost")` from the macro path) twice in one session: first with --inches (not
optimized), then optimized in mm. The second post must be G21 (the wrapped post's options no longer
leak), and LinuxCNC's interpreter `rs274` must read the optimized program as the posted path with
only feeds changed. Skipped when FreeCAD (or rs274) is absent."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import rs274_oracle
from millpost.machine import Machine

ROOT = Path(__file__).resolve().parents[1]
FREECADCMD = shutil.which("freecadcmd")

pytestmark = pytest.mark.skipif(FREECADCMD is None, reason="FreeCAD is not installed (apt-get install freecad)")


@pytest.fixture(scope="module")
def posted(tmp_path_factory):
    out = tmp_path_factory.mktemp("freecad")
    exe = out / "millpost"
    exe.write_text(f"#!{sys.executable}\nimport sys\nsys.path.insert(0, {str(ROOT / 'src')!r})\n"
                   "from millpost.cli import main\nsys.exit(main())\n")
    exe.chmod(0o755)
    env = {**os.environ, "MILLPOST_FC_OUT": str(out), "MILLPOST_FC_POSTS": str(ROOT / "posts" / "freecad"),
           "MILLPOST_FC_EXE": str(exe), "MILLPOST_FC_RESULT": str(out / "result.json"),
           "HOME": str(out)}  # FreeCAD's user settings go to a fresh home, not the user's
    done = subprocess.run([FREECADCMD, str(ROOT / "tests" / "freecad" / "post_job.py")], env=env, cwd=out,
                          capture_output=True, text=True, timeout=1800)
    result_file = out / "result.json"
    assert result_file.exists(), done.stdout[-3000:] + done.stderr[-3000:]
    result = json.loads(result_file.read_text())
    assert result["ok"], result.get("error")
    return out, result, done.stdout


def test_real_freecad_posts_both_operations_and_options_do_not_leak(posted):
    out, result, log = posted
    assert result["moves"]["Adaptive"] > 50 and result["moves"]["Pocket"] > 5
    assert all(p["returned_equals_file"] for p in result["posts"])
    inch = (out / "inch.ngc").read_text()
    mm = (out / "mm.posted.ngc").read_text()
    assert "G20" in inch
    assert "G21" in mm and "G20" not in mm  # after the --inches post, the next post is metric again
    assert "millpost: optimised" in log


@pytest.mark.skipif(rs274_oracle.RS274 is None, reason="LinuxCNC's rs274 is not installed")
def test_optimized_program_is_the_posted_path_for_rs274(posted):
    out, _, _ = posted
    before = rs274_oracle.run(out / "mm.posted.ngc")
    after = rs274_oracle.run(out / "mm.ngc")
    for trace in (before, after):
        assert trace.error is None or "%" in trace.error, trace.error
    assert (out / "mm.ngc").read_text() != (out / "mm.posted.ngc").read_text()  # it was optimized
    ends_b = np.array([m[1] for m in before.moves])
    ends_a = np.array([m[1] for m in after.moves])
    # every posted move ends where an optimized one does, in order (moves may be split, never changed)
    k = 0
    for p in ends_b:
        while k < len(ends_a) and np.abs(ends_a[k] - p).max() > 1e-3:
            k += 1
        assert k < len(ends_a), f"posted end point {p} is missing from the optimized program"
        k += 1
    vmax = Machine.load("vmc-small").feed_cap_mm_min
    feeds = [m[2] for m in after.moves if m[0] != "rapid" and m[2] is not None]
    assert feeds and max(feeds) <= vmax + 1e-6
