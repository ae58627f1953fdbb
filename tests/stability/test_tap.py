"""`millpost tap`: modes from synthetic hammer tests and the chatter frequency from synthetic chattering cuts.

The generators here use no millpost code: a tap log is the hammer's half-sine force pulses driven through
uncoupled modes by integrating m_i q_i'' + c_i q_i' + k_i q_i = F(t) with scipy's solve_ivp (DOP853), the
tool tip's motion x = Σ q_i; a chattering cut is spindle and tooth-passing harmonics plus a component at
f_c that grows (1 − e^(−t/0.2 s)) to a limit cycle, in white noise. The fit must recover what went in:
f_n within 1 %, ζ within 10 %, k within 5 % (issue 30), f_c within 1 %, the speeds 60 f_c/(N j)."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from millpost.cli import main
from millpost.errors import ParseError
from millpost.stability.tap import ModalFit, analyse_chatter, read_recording, read_tap_log

HITS = tuple(0.05 + 0.3 * i for i in range(6))     # six hits 0.3 s apart (each rings down before the next)
ONE = [(900.0, 0.03, 2.0e4)]                       # (f_n Hz, ζ, k N/mm)
TWO = [(650.0, 0.035, 1.5e4), (1500.0, 0.03, 2.5e4)]


def tap_log(path: Path, modes, *, hits=(0.05, 0.45, 0.85, 1.25), duration_s=1.65, fs_hz=51200.0,
            peak_N=300.0, pulse_s=2.5e-4, noise=0.03, response="accel_m_s2", seed=0, clip_N=None) -> Path:
    """Write a tap log: modes as (fn Hz, ζ, k N/mm); Gaussian noise σ = `noise` × each channel's peak."""
    wn = [2 * math.pi * fn for fn, _, _ in modes]
    m = [k * 1e3 / w**2 for (_, _, k), w in zip(modes, wn)]           # kg (k in N/m)

    def force(t):
        return sum(peak_N * math.sin(math.pi * (t - h) / pulse_s) for h in hits if h <= t <= h + pulse_s)

    def rhs(t, y):
        f = force(t)
        out = []
        for i, (_, z, _) in enumerate(modes):
            q, v = y[2 * i], y[2 * i + 1]
            out += [v, f / m[i] - 2 * z * wn[i] * v - wn[i] ** 2 * q]
        return out

    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    y, y0 = np.zeros((2 * len(modes), len(t))), np.zeros(2 * len(modes))
    edges = sorted({0.0, t[-1], *hits, *(h + pulse_s for h in hits)})
    for a, b in zip(edges[:-1], edges[1:]):   # short steps on a pulse, free vibration between pulses
        sol = solve_ivp(rhs, (a, b), y0, method="DOP853", rtol=1e-10, atol=1e-16, dense_output=True,
                        max_step=pulse_s / 8 if a in hits else np.inf)
        on = (t >= a) & (t <= b)
        y[:, on], y0 = sol.sol(t[on]), sol.y[:, -1]
    f = np.array([force(ti) for ti in t])
    q = y[0::2]
    v = y[1::2]
    a = np.array([f / mi - 2 * z * w * vi - w**2 * qi for (_, z, _), w, mi, qi, vi in zip(modes, wn, m, q, v)])
    resp = {"accel_m_s2": a.sum(0), "vel_mm_s": 1e3 * v.sum(0), "disp_mm": 1e3 * q.sum(0)}[response]
    rng = np.random.default_rng(seed)
    f_noisy = f + noise * peak_N * rng.standard_normal(len(t))
    r_noisy = resp + noise * np.max(np.abs(resp)) * rng.standard_normal(len(t))
    if clip_N is not None:
        f_noisy = np.minimum(f_noisy, clip_N)
    np.savetxt(path, np.column_stack([t, f_noisy, r_noisy]), delimiter=",", header=f"t_s,force_N,{response}",
               comments="", fmt="%.9g")
    return path


def chatter_recording(path: Path, *, rpm, flutes, f_chatter_hz, fs_hz=20000.0, duration_s=2.0, noise=0.05,
                      seed=0, rpm_column=False, chatter=2.0) -> Path:
    """Write a recording: spindle and tooth-passing harmonics (runout: a little of every spindle harmonic)
    plus a chatter component at f_chatter_hz growing as 1 − exp(−t/0.2 s) to `chatter` × the tooth-passing
    amplitude (0: a stable cut), and white noise of σ = `noise` × the tooth-passing amplitude."""
    rng = np.random.default_rng(seed)
    t = np.arange(int(duration_s * fs_hz)) / fs_hz
    fs_ = rpm / 60.0
    x = np.zeros_like(t)
    for k in range(1, int(0.45 * fs_hz / fs_)):
        amp = (1.0 / (k // flutes) if k % flutes == 0 else 0.1 / k)
        x += amp * np.sin(2 * math.pi * k * fs_ * t + rng.uniform(0, 2 * math.pi))
    x += chatter * (1 - np.exp(-t / 0.2)) * np.sin(2 * math.pi * f_chatter_hz * t + 0.3)
    x += noise * rng.standard_normal(len(t))
    cols, names = [t, x], "t_s,signal"
    if rpm_column:
        cols.append(np.full_like(t, rpm))
        names += ",spindle_rpm"
    np.savetxt(path, np.column_stack(cols), delimiter=",", header=names, comments="", fmt="%.9g")
    return path


def _check(modes, true):
    assert len(modes) == len(true)
    for m, (fn, z, k) in zip(modes, true):
        assert m.fn_hz == pytest.approx(fn, rel=0.01)
        assert m.zeta == pytest.approx(z, rel=0.10)
        assert m.k_N_per_mm == pytest.approx(k, rel=0.05)


@pytest.mark.parametrize("response", ["accel_m_s2", "vel_mm_s", "disp_mm"])
def test_one_mode_with_5_percent_noise(tmp_path, response):
    log = tap_log(tmp_path / "tap.csv", ONE, hits=HITS[:4], duration_s=1.3, noise=0.05, response=response)
    fit = ModalFit().fit(read_tap_log(log))
    _check(fit.modes_, ONE)
    assert fit.r2_ > 0.99 and fit.coherence_ > 0.95 and len(fit.measured_.hits.starts) == 4
    assert abs(fit.predict([900.0])[0]) == pytest.approx(1 / (2 * 2e4 * 0.03), rel=0.1)   # |G(f_n)| = 1/(2kζ)


@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_one_mode_is_one_mode(tmp_path, seed):
    """The mode count is chosen (no --modes): noise bumps of the receptance (an accelerometer's G = A/s²
    amplifies noise at low frequency; the first version took bumps at 238 and 365 Hz for modes) are left out."""
    log = tap_log(tmp_path / "tap.csv", ONE, hits=HITS[:4], duration_s=1.3, noise=0.05, seed=seed)
    _check(ModalFit().fit(read_tap_log(log)).modes_, ONE)


@pytest.mark.parametrize("seed", [0, 1, 2, 3, 4])
def test_two_modes_with_3_percent_noise(tmp_path, seed):
    log = tap_log(tmp_path / "tap.csv", TWO, hits=HITS, duration_s=1.9, noise=0.03, seed=seed)
    fit = ModalFit().fit(read_tap_log(log))      # the count, 2, is chosen by the fit
    _check(fit.modes_, TWO)
    # the automatic window τ = 2/σ of the slower decay (σ = ζω_n of the 650 Hz mode: 143 /s): about 14 ms
    assert fit.measured_.tau_s == pytest.approx(2 / (0.035 * 2 * math.pi * 650), rel=0.15)


def test_a_given_window_gives_the_same_modes(tmp_path):
    """The window's added damping is taken out: a short and a long window agree (noise-free log)."""
    log = read_tap_log(tap_log(tmp_path / "tap.csv", TWO, hits=HITS[:3], duration_s=1.0, noise=0.0))
    for tau in (0.005, 0.05):
        _check(ModalFit(2, window_s=tau).fit(log).modes_, TWO)


def test_bad_tap_logs(tmp_path):
    good = tap_log(tmp_path / "tap.csv", ONE, hits=HITS[:2], duration_s=0.7, noise=0.02)
    rows = good.read_text().splitlines()
    (tmp_path / "nocol.csv").write_text("\n".join(r.rsplit(",", 1)[0] for r in rows) + "\n")
    with pytest.raises(ParseError, match=r"nocol.csv:1:1: no response columns.*exactly one of accel_m_s2"):
        read_tap_log(tmp_path / "nocol.csv")
    (tmp_path / "word.csv").write_text("\n".join(rows[:5] + [rows[5].replace(",", ",x", 1)] + rows[6:]) + "\n")
    with pytest.raises(ParseError, match=r"word.csv:6:\d+: not a number in column force_N"):
        read_tap_log(tmp_path / "word.csv")
    quiet = tap_log(tmp_path / "quiet.csv", ONE, hits=(), duration_s=0.3, noise=0.02)
    with pytest.raises(ParseError, match=r"no hammer hit found"):
        ModalFit().fit(read_tap_log(quiet))
    clipped = tap_log(tmp_path / "clip.csv", ONE, hits=HITS[:2], duration_s=0.7, noise=0.01, clip_N=200.0)
    with pytest.raises(ParseError, match=r"clip.csv:\d+:2: force_N is clipped.*expected a hit within the sensor"):
        ModalFit().fit(read_tap_log(clipped))


def test_a_double_hit_is_left_out(tmp_path):
    log = tap_log(tmp_path / "tap.csv", ONE, hits=(0.05, 0.35, 0.352, 0.65, 0.95), duration_s=1.25, noise=0.02)
    fit = ModalFit(1).fit(read_tap_log(log))
    assert len(fit.measured_.hits.starts) == 3 and len(fit.notes_) == 1
    assert fit.notes_[0].startswith("double hit at t = 0.35 s (a second pulse 2.0")
    _check(fit.modes_, ONE)


@pytest.mark.parametrize("rpm, flutes, fc", [(9000, 3, 1234.0), (12000, 2, 880.0), (6000, 4, 2311.0)])
def test_chatter_frequency_and_stable_speeds(tmp_path, rpm, flutes, fc):
    rec = read_recording(chatter_recording(tmp_path / "cut.csv", rpm=rpm, flutes=flutes, f_chatter_hz=fc))
    c = analyse_chatter(rec, rpm, flutes, rpm_max=15000)
    assert c.chatter and c.peak_to_floor > 1e5 > c.threshold    # 50 dB above the floor
    assert c.f_chatter_hz == pytest.approx(fc, rel=0.01)
    ft = flutes * rpm / 60
    assert c.lobe == int(fc // ft) and c.epsilon_rad == pytest.approx(2 * math.pi * (fc / ft - c.lobe), abs=0.1)
    j0 = math.ceil(60 * c.f_chatter_hz / (flutes * 15000))
    assert [j for j, _ in c.speeds] == list(range(j0, j0 + 5))
    for j, n in c.speeds:
        assert n == pytest.approx(60 * c.f_chatter_hz / (flutes * j), rel=1e-12) and n <= 15000
        assert n == pytest.approx(60 * fc / (flutes * j), rel=0.01)


@pytest.mark.parametrize("rpm, flutes", [(9000, 3), (12000, 2), (6000, 4)])
@pytest.mark.parametrize("seed", [0, 1])
def test_a_stable_cut_has_no_chatter(tmp_path, rpm, flutes, seed):
    """Harmonics and white noise only: no peak passes the threshold (the noise's χ² statistics, 1 % false
    alarms over the spectrum), no speeds; a weak chatter 1/100 of the tooth passing's is found."""
    rec = read_recording(chatter_recording(tmp_path / "cut.csv", rpm=rpm, flutes=flutes, f_chatter_hz=1234.0,
                                           chatter=0.0, seed=seed))
    c = analyse_chatter(rec, rpm, flutes)
    assert not c.chatter and c.speeds == () and 1.0 < c.peak_to_floor < c.threshold < 4.0
    weak = read_recording(chatter_recording(tmp_path / "weak.csv", rpm=rpm, flutes=flutes, f_chatter_hz=1234.0,
                                            chatter=0.01, seed=seed))
    c = analyse_chatter(weak, rpm, flutes)
    assert c.chatter and c.f_chatter_hz == pytest.approx(1234.0, rel=0.001) and len(c.speeds) == 5


def test_cli_fit_and_chatter(tmp_path, capsys):
    log = tap_log(tmp_path / "tap.csv", ONE, hits=HITS[:4], duration_s=1.3, noise=0.03)
    assert main(["tap", "fit", str(log), "--direction", "y", "--json", str(tmp_path / "m.json")]) == 0
    assert capsys.readouterr().out.startswith("y mode 1: fn 9")
    out = json.loads((tmp_path / "m.json").read_text())["y"]
    _check([type("M", (), m) for m in out["modes"]], ONE)
    assert out["log"] == str(log) and out["hits"] == 4 and out["r2"] > 0.99
    assert main(["tap", "fit", str(log), "--toml", str(log)]) == 2          # never overwrites its input
    assert "same file as the input" in capsys.readouterr().err
    assert main(["tap", "fit", str(log), "--direction", "y", "--toml", str(tmp_path / "f.toml")]) == 2
    assert "needs x" in capsys.readouterr().err and not (tmp_path / "f.toml").exists()

    rec = chatter_recording(tmp_path / "cut.csv", rpm=9000, flutes=3, f_chatter_hz=1234.0, rpm_column=True)
    assert main(["tap", "chatter", str(rec), "--flutes", "3", "--spindle-max", "12000", "--json", "-"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["chatter"] and out["rpm"] == 9000 and out["f_chatter_hz"] == pytest.approx(1234.0, rel=0.01)
    assert [s["j"] for s in out["speeds"]] == [3, 4, 5, 6, 7]
    assert out["speeds"][0]["rpm"] == pytest.approx(60 * 1234.0 / 9, rel=0.01)
    stable = chatter_recording(tmp_path / "stable.csv", rpm=9000, flutes=3, f_chatter_hz=1234.0, chatter=0.0)
    assert main(["tap", "chatter", str(stable), "--flutes", "3", "--rpm", "9000", "--json", "-"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["chatter"] is False and out["speeds"] == []
    assert main(["tap", "chatter", str(stable), "--flutes", "3", "--rpm", "9000"]) == 0
    assert capsys.readouterr().out.startswith("no chatter found: the strongest")
    assert main(["tap", "chatter", str(log), "--flutes", "3", "--rpm", "9000"]) == 2     # a tap log is no recording
    assert "unknown column 'force_N'" in capsys.readouterr().err


def test_x_and_y_in_one_fragment_the_job_reads(tmp_path, capsys):
    """`tap fit LOGX LOGY --toml` writes one [tools.N.frf] table with x = [...] and y = [...]; pasted into a
    job, load_job gives the modes the fit printed (to the fragment's 6 digits) and those that went in."""
    from millpost.job import load_job
    logx = tap_log(tmp_path / "tap-x.csv", ONE, hits=HITS[:4], duration_s=1.3, noise=0.03)
    logy = tap_log(tmp_path / "tap-y.csv", TWO, hits=HITS, duration_s=1.9, noise=0.03, seed=1)
    assert main(["tap", "fit", str(logx), str(logy), "--tool", "1", "--json", str(tmp_path / "m.json"),
                 "--toml", str(tmp_path / "frf.toml")]) == 0
    fitted = json.loads((tmp_path / "m.json").read_text())
    fragment = (tmp_path / "frf.toml").read_text()
    assert fragment.count("[tools.1.frf]") == 1 and "\nx = [" in fragment and "\ny = [" in fragment
    slot = Path(__file__).resolve().parents[2] / "sample_jobs" / "chatter_slot"
    (tmp_path / "program.nc").write_text((slot / "program.nc").read_text())
    job = (slot / "job.toml").read_text()
    (tmp_path / "job.toml").write_text(job[:job.index("[tools.1.frf]")] + fragment)
    frf = load_job(tmp_path).frf[1]
    for direction, true in (("x", ONE), ("y", TWO)):
        modes = getattr(frf, direction).modes
        _check(modes, true)
        for m, f in zip(modes, fitted[direction]["modes"]):
            assert (m.fn_hz, m.zeta, m.k_N_per_mm) == pytest.approx((f["fn_hz"], f["zeta"], f["k_N_per_mm"]), rel=1e-3)
    assert main(["tap", "fit", str(logx), str(logy), "--direction", "x"]) == 2
    assert "no --direction with two logs" in capsys.readouterr().err


@pytest.mark.parametrize("args, message", [
    (["--spindle-max", "0"], "spindle max rpm = 0: expected > 0"),
    (["--spindle-min", "9000", "--spindle-max", "8000"], "spindle max rpm = 8000: expected > 0 and ≥ the spindle min"),
    (["--spindle-min", "-1"], "spindle min rpm = -1: expected ≥ 0"),
    (["--speeds", "-1"], "stable speeds listed = -1: expected at least 1"),
    (["--speeds", "0"], "stable speeds listed = 0"),
    (["--rpm", "0"], "rpm = 0: expected a spindle speed > 0"),
    (["--rpm", "nan"], "rpm = nan"),
    (["--flutes", "0"], "flutes = 0: expected at least 1"),
    (["--rpm", "1e9"], "with 3 flutes, 5e+07 Hz, is not below the recording's Nyquist frequency 10000 Hz"),
])
def test_cli_chatter_refuses_bad_options(tmp_path, capsys, args, message):
    """Each bad option is a one-line error naming it and the value (formerly ZeroDivisionError, scipy's
    nperseg ValueError, or accepted), exit status 2."""
    rec = chatter_recording(tmp_path / "cut.csv", rpm=9000, flutes=3, f_chatter_hz=1234.0)
    flutes = [] if "--flutes" in args else ["--flutes", "3"]
    rpm = [] if "--rpm" in args else ["--rpm", "9000"]
    assert main(["tap", "chatter", str(rec), *flutes, *rpm, *args]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


@pytest.mark.parametrize("seed", [0, 1])
def test_flip_chatter_on_a_spindle_harmonic_with_an_even_flute_count(tmp_path, seed, capsys):
    """N = 4 at 9000 rpm: period-doubling chatter at 2.5·f_t = 1500 Hz is the 10th spindle harmonic, hidden by
    the harmonic mask (the verdict was "chatter: 1482.5 Hz", a leakage shoulder, or none). Twice the
    tooth-passing amplitude stands 44 dB above the 9th and 11th harmonics (runout, 0.1/k): found at 1500 Hz,
    lobe 2, ε = π. A stable cut of the same tool is not called flip chatter, and notes that weak flip chatter
    cannot be told from runout."""
    rec = read_recording(chatter_recording(tmp_path / "cut.csv", rpm=9000, flutes=4, f_chatter_hz=1500.0,
                                           seed=seed))
    c = analyse_chatter(rec, 9000, 4)
    assert c.chatter and c.period_doubling and c.f_chatter_hz == 1500.0
    assert c.lobe == 2 and c.epsilon_rad == pytest.approx(math.pi) and c.peak_to_floor > 1e4 and c.notes == []
    assert c.speeds[0] == (1, pytest.approx(22500.0))
    stable = read_recording(chatter_recording(tmp_path / "stable.csv", rpm=9000, flutes=4, f_chatter_hz=1500.0,
                                              chatter=0.0, seed=seed))
    c = analyse_chatter(stable, 9000, 4)
    assert not c.chatter and not c.period_doubling and "cannot be told from runout" in c.notes[0]
    assert main(["tap", "chatter", str(rec.path), "--rpm", "9000", "--flutes", "4"]) == 0
    assert "chatter: 1500.0 Hz (44." in capsys.readouterr().out
