"""The measurement log format (millpost.measure.log): round trips, clear errors, and alignment of a log
shifted by an unknown offset and resampled (millpost.measure.align)."""

from __future__ import annotations

import numpy as np
import pytest

from millpost import signals
from millpost.errors import ParseError
from millpost.measure import Gap, Log, LogWriter, align, read_log, write_log
from millpost.measure.synthetic import synthetic_log

from test_signals import make_job

PROGRAM = """G21 G90 G94 G17
T1 M6
S8000 M3
G0 X-5 Y5 Z5
G1 Z-2 F300
G1 X45 F500
G0 Z5
G0 X-5 Y15
G1 Z-3 F300
G1 X20 F900
G1 X45 F400
G0 Z5
G0 X-5 Y25
G1 Z-1.5 F300
G1 X45 F1200
G0 Z5
M5
M30
"""


@pytest.fixture(scope="module")
def predicted(tmp_path_factory):
    job = make_job(tmp_path_factory.mktemp("align"), PROGRAM)
    return signals.simulate(job)


def test_csv_and_npz_round_trip(tmp_path):
    log = Log({"t_s": np.array([0.0, 0.01, 0.02]), "fx_N": np.array([1.5, np.nan, -2.0]),
               "line": np.array([3.0, 3.0, 4.0]), "output_frequency_Hz": np.array([100.0, 100.5, 101.0])},
              [Gap(0.005, 0.007, "timeout")], {"source": "test"})
    for name in ("a.csv", "a.npz"):
        write_log(tmp_path / name, log)
        back = read_log(tmp_path / name)
        assert list(back.columns) == list(log.columns)
        for k in log.columns:
            np.testing.assert_allclose(back[k], log[k], equal_nan=True)
        assert back.gaps == log.gaps and back.meta == log.meta


@pytest.mark.parametrize("text, where, word", [
    ("t_s,fx_N\n0,1\n0.1,abc\n", ":3:5", "abc"),
    ("t_s,fx_N\n0,1\n0.1\n", ":3:4", None),
    ("t_s,force\n0,1\n", ":1:5", "force"),
    ("fx_N\n1\n", ":1:1", None),
    ("# c\nt_s,fx_N\n0,1\n0.2,1\n0.1,1\n", ":5:1", "0.1"),
    ("t_s,fx_N,fx_N\n0,1,1\n", ":1:10", "fx_N"),
])
def test_bad_logs_name_file_row_column(tmp_path, text, where, word):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(ParseError) as e:
        read_log(p)
    assert f"bad.csv{where}:" in str(e.value)
    if word:
        assert e.value.word == word
    assert e.value.expected


def test_writer_keeps_rows_and_gaps(tmp_path):
    with LogWriter(tmp_path / "w.csv", ["t_s", "spindle_current_A"], {"rate_hz": "50"}) as w:
        w.row([0.0, 1.25])
        w.gap(Gap(0.02, 0.06, "timeout"))
        w.row([0.08, float("nan")])
        assert not (tmp_path / "w.csv").exists()  # written whole, at close
    log = read_log(tmp_path / "w.csv")
    assert len(log) == 2 and log.gaps == [Gap(0.02, 0.06, "timeout")] and log.meta["rate_hz"] == "50"


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("positions", [False, True])
@pytest.mark.parametrize("coarse_points, fine_points", [(1 << 18, 1 << 18), (1 << 10, 1 << 14)])
def test_alignment_within_one_sample(predicted, seed, positions, coarse_points, fine_points, monkeypatch):
    # (one FFT pass over the whole log; or a coarse pass, then the log's interval on a window)
    monkeypatch.setattr("millpost.measure.xcorr.COARSE_POINTS", coarse_points)
    monkeypatch.setattr("millpost.measure.xcorr.FINE_POINTS", fine_points)
    rng = np.random.default_rng(100 + seed)
    offset = float(rng.uniform(0.1, 3.0))
    rate = float(rng.choice([100.0, 250.0, 1000.0]))
    cols = ("fx_N", "fy_N", "spindle_power_W") + (("x_mm", "y_mm", "z_mm") if positions else ())
    log = synthetic_log(predicted, rate_hz=rate, offset_s=offset, noise=float(rng.uniform(0.02, 0.05)), columns=cols,
                        lead_s=float(rng.uniform(0, 2)), tail_s=1.0, position_noise_mm=0.002, seed=seed)
    # the logger's clock starts at an arbitrary epoch
    epoch = float(rng.uniform(-50, 50))
    log.columns["t_s"] = log.columns["t_s"] + epoch
    a = align(log, predicted)
    truth = log.t_s - (offset + epoch)
    inside = (truth > predicted.t_s[0]) & (truth < predicted.t_s[-1])
    assert a.method == ("position" if positions else "xcorr")
    if positions:   # every row's program time: where the tool moves, to its sample interval
        moving = inside & (np.interp(truth, predicted.t_s, predicted.speed_mm_s) > 1.0)
        err = np.abs(a.tau_s[moving] - truth[moving])
        assert np.median(err) < 0.5 / rate and np.quantile(err, 0.99) < 2.0 / rate, (np.median(err), err.max())
        assert a.position_rms_mm < 0.05
    else:
        assert abs(a.offset_s - (offset + epoch)) < 1.0 / rate, (a.offset_s, offset + epoch, a.method)
        assert a.correlation > 0.8


def test_empty_position_columns_fall_back_to_the_time_offset(predicted):
    """Position columns that hold no value (a logger that declared but never filled them) are no positions:
    the offset comes from cross-correlation, not a refusal."""
    log = synthetic_log(predicted, rate_hz=250.0, offset_s=1.3, noise=0.03, columns=("fx_N", "fy_N"), lead_s=0.5,
                        tail_s=0.5, seed=3)
    for c in ("x_mm", "y_mm", "z_mm"):
        log.columns[c] = np.full(len(log), np.nan)
    a = align(log, predicted)
    assert a.method == "xcorr" and abs(a.offset_s - 1.3) < 1.0 / 250.0
