"""Shared test fixtures: where the real third-party material lives (../shared/data); which suites are slow."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

SHARED_DATA = Path(__file__).resolve().parents[1].parent / "shared" / "data"


def shared_data(*parts: str) -> Path:
    """A path under ../shared/data, or skip the test with a clear reason when it is absent."""
    path = SHARED_DATA.joinpath(*parts)
    if not path.exists():
        pytest.skip(f"{path} is absent (../shared/data holds third-party material, not in the repo)")
    return path


# The long suites, marked `slow` here in one place: `pytest -m "not slow"` is the fast set, CI runs
# everything. A key is a node id prefix (a file, a test, one parametrized case) and may hold `*` (any
# text). Seconds: measured on the shared 2-core machine while others ran (load 6-9), module fixtures and
# first-run compiles included.
SLOW = {
    "tests/test_random_jobs.py": "1000 seeded random jobs end to end",
    "tests/test_real_jobs.py": "the real-program regression set through optimize, on every machine",
    "tests/controller/test_controller_lcnc.py": "LinuxCNC's planner in its simulator (60-100 s a program)",
    "tests/test_freecad_real.py": "FreeCAD 0.20 headless posting a job",
    "tests/report/test_report_browser.py": "headless Chromium opening the report: 14 s",
    "tests/discover/test_discover.py::test_seeded_runs_name_the_hidden_effect": "3 seeded runs per effect: 680 s",
    "tests/discover/test_discover.py::test_runout_at_1_khz_null_run_names_nothing": "a 1 kHz run: 25 s",
    "tests/discover/test_discover_independent.py": "independent runs, one per hidden effect: over 10 min",
    "tests/discover/test_discover.py::test_cli_end_to_end_reviewer_format": "discover's CLI on a measured run: 16 s",
    "tests/calibrate/test_calibrate_independent.py": "fits of independently generated logs: 75 s",
    "tests/calibrate/test_calibrate_prior.py": "the independent generator's slots: 15 s",
    "tests/test_docs.py::test_the_commands_of_a_page_run": "every command of every page: 330 s",
    "tests/test_machinist_bars.py": "CAM-style pockets through optimize, read as a machinist: 150 s",
    "tests/test_plugins.py": "third-party wheels built and installed by pip: 45 s",
    "tests/test_optimize.py::*[adaptive_pocket]": "5 of the 7 sample jobs (slotting and forging_contour stay fast): 50 s",
    "tests/test_optimize.py::*[ball_roughing]": "",
    "tests/test_optimize.py::*[drill_and_mill]": "",
    "tests/test_optimize.py::*[offset_pocket]": "",
    "tests/test_optimize.py::*[sawcut_facing]": "",
    "tests/test_low_deflection.py::test_every_built_in_machine_diameter_and_material": "27 low-deflection searches: 85 s",
    "tests/test_spindle_speed.py::test_s_at_its_best_stays": "rpm = optimize on whole jobs, three tests: 38 s",
    "tests/test_spindle_speed.py::test_a_faster_s_in_the_window_shortens_the_cycle": "",
    "tests/test_spindle_speed.py::test_a_failed_schedule_keeps_the_programmed_s": "",
    "tests/test_batch.py::test_batch_gives_what_each_job_gives_alone": "a Dask cluster of 2 workers: 26 s",
    "tests/test_progress.py::test_progress_on_a_terminal_only": "the CLI on a pty, several runs: 29 s",
    "tests/test_engagement.py::test_undercut_column_cut_through_its_top_interval": "a B-rep stock at 0.05 mm: 38 s",
    "tests/test_engagement_volume.py::test_removed_volume_matches_exact_booleans": "manifold3d booleans: 28 s",
    "tests/gcode/test_gcode_corpus.py": "217 real programs, each through rs274: 63 s",
    "tests/gcode/test_convert.py::test_round_trip_through_own_dialect_and_grbl": "the corpus in every dialect: 23 s",
    "tests/gcode/test_convert_semantics.py::test_corpus_machine_motion_survives_every_dialect": "rs274: 22 s",
    "tests/gcode/test_fuzz.py::test_mutants_are_read_or_refused_never_crash": "3000 seeded mutants: 39 s",
    "tests/gcode/test_sinumerik_fuzz.py::test_mutants_are_read_or_refused_never_crash": "3000 seeded mutants: 25 s",
    "tests/gcode/test_heidenhain_fuzz.py::test_mutants_are_read_or_refused_never_crash": "1500 seeded mutants: 15 s",
    "tests/gcode/test_gcode_reader.py::test_fuzz_never_crashes": "400 hypothesis examples: 17 s",
    "tests/gcode/test_reader_strict.py::test_loops_pecks_and_repeats_are_capped": "programs run to the caps: 17 s",
    "tests/gcode/test_cutter_comp.py::test_random_contours_match_rs274": "random contours through rs274: 13 s",
    "tests/emit/test_emit.py::test_split_moves_keep_the_path_and_take_each_feed": "40 corpus programs, rs274: 100 s",
    "tests/emit/test_emit.py::test_scaled_feeds_are_written_and_read_back": "40 corpus programs: 23 s",
    "tests/measure/test_modbus_log.py::test_logger_survives_a_vanishing_server": "10 s and 3 s of real-time logging",
    "tests/measure/test_modbus_log.py::test_ctrl_c_ends_with_a_complete_file": "a real-time logger run: 11 s",
    "tests/report/test_report.py::test_cli_optimize_report_and_report_from_trace": "optimize and report runs: 21 s",
    "tests/schedule/test_schedule.py::test_seeded_random_problems_exceed_no_limit": "random problems: 20 s",
    "tests/schedule/test_schedule_certify.py": "40 random jobs against Clarabel: 16 s",
    "tests/stability/test_lobes.py::test_semi_discretisation_agrees_with_zero_order_in_slotting": "64-step semi-discretisation: 16 s",
    "tests/compensate/test_compensate.py::test_independent_check_of_the_compensated_program": "a 10 µm height field cut sample by sample: 31-64 s",
    "tests/schedule/test_solver_choice.py::test_auto_and_clarabel_agree_on_the_adaptive_pocket": "2 optimizes: 10 s",
}
_SLOW = re.compile("|".join(re.escape(k).replace(r"\*", ".*") + r"(?:$|::|\[)" for k in SLOW))


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config, items):
    """Marks the suites of SLOW `slow` (before `-m` selects); a SLOW file that is gone is an error, so that
    a move cannot silently turn a long suite into a fast one."""
    root = Path(__file__).resolve().parents[1]
    for key in SLOW:
        if not (root / key.split("::")[0]).is_file():
            raise pytest.UsageError(f"conftest.SLOW names {key}, whose file is absent")
    for item in items:
        if _SLOW.match(item.nodeid):
            item.add_marker(pytest.mark.slow)


@pytest.fixture(scope="session")
def slotting_result():
    """The slotting sample job optimized once per session: (job, Result)."""
    from millpost.job import load_job
    from millpost.optimize import optimize
    job = load_job(Path(__file__).resolve().parents[1] / "sample_jobs" / "slotting")
    return job, optimize(job, progress=False, trace=True, surface_error=True)
