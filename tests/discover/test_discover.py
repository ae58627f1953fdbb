"""millpost discover: seeded measured runs with one hidden effect each (tests/discover_runs.py, an
independent angle-domain simulation), the CLI end to end on a reviewer-format log, the effect registry,
and the UMich drive currents (real data: axis friction from an inertia-only model)."""

from __future__ import annotations

import csv
import json
import os

import numpy as np
import pytest

from millpost.cli import main
from millpost.discover.rows import from_axis_arrays
from millpost.discover.run import discover
from millpost.discover.search import candidates, select
from millpost.job import load_job
from millpost.measure.log import read_log, write_log

from conftest import shared_data
from discover_runs import EFFECTS, make_run

NAMES = ("tool_wear", "size_effect", "deflection", "inertia", "sensor_lag", "spindle_no_load", "sensor_drift",
         "axis_friction", "runout")
# seeds per effect: 3 in the shared suite (fast), MILLPOST_DISCOVER_RUNS=10 for the full bar
RUNS = int(os.environ.get("MILLPOST_DISCOVER_RUNS", "3"))


@pytest.fixture(scope="module")
def cache(tmp_path_factory):
    return {"dir": tmp_path_factory.mktemp("runs"), "signals": {}}


def run_one(cache, effect: str, seed: int):
    folder = cache["dir"] / f"job{seed}"
    r = make_run(folder, seed, effect, signals_cache=cache["signals"])
    d = discover(load_job(r.job_path), r.log, signals=cache["signals"][str(r.job_path)])
    return r, d.summary(), d.predictions()


def raw_shrink(pred: dict, channels: list[str]) -> float:
    """Median over the channels of 1 − RMS(after)/RMS(before) on the held-out rows, from the predictions
    table alone (what `--predictions` writes)."""
    held = pred["held_out"] == 1
    out = []
    for c in channels:
        before = np.sqrt(np.mean((pred[f"{c}_measured"] - pred[f"{c}_before"])[held] ** 2))
        after = np.sqrt(np.mean((pred[f"{c}_measured"] - pred[f"{c}_after"])[held] ** 2))
        out.append(1 - after / before)
    return float(np.median(out))


def test_registry_has_the_named_effects():
    found = candidates()
    assert set(NAMES) <= set(found)
    for name, cls in found.items():
        assert cls.name == name and cls.channels


@pytest.mark.parametrize("effect", EFFECTS)
def test_seeded_runs_name_the_hidden_effect(cache, effect):
    named, shrink, rho = [], [], []
    runs = RUNS if effect != "runout" else max(RUNS // 3, 1)   # 1 kHz logs: ten times the rows
    for seed in range(runs):
        r, s, pred = run_one(cache, effect, seed)
        names = [e["name"] for e in s["effects"]]
        named.append(names[0] if names else "none")
        if names and names[0] == effect:
            shrink.append(raw_shrink(pred, s["effects"][0]["channels"]))
            if effect == "runout" and s["effects"][0]["params"].get("eccentricity_mm") is not None:
                rho.append(s["effects"][0]["params"]["eccentricity_mm"] / r.truth["runout_mm"])
    right = sum(n == effect for n in named)
    print(f"{effect}: named {named}, held-out RMS shrink {np.round(shrink, 2).tolist()}"
          + (f", eccentricity found/true {np.round(rho, 3).tolist()}" if rho else ""))
    if effect == "none":
        assert right >= 0.95 * runs, named   # no false alarm
        return
    assert right >= 0.9 * runs - 1e-9 or right >= runs - 1, named
    if effect == "runout":   # 1 to 3 runs (the figures of docs/discover.md): the bar on their median
        assert np.median(shrink) >= 0.6, shrink
        assert all(abs(q - 1) < 0.15 for q in rho), rho   # the axis offset ρ (3 and 4 flutes): 0.94–1.08
        return
    # the bar (median over 10 runs ≥ 0.6); a few runs scatter more (single runs go from 0.44 to 0.95)
    bar = 0.6 if runs >= 10 else 0.45
    assert np.median(shrink) >= bar, shrink


def test_runout_at_100_hz_is_said_not_seen(cache):
    """A 100 Hz log of a runout run: once-per-revolution content (67–167 Hz here) is above the log's
    Nyquist frequency, so discover names nothing and its notes say why."""
    r = make_run(cache["dir"] / "job0", 0, "runout", rate_hz=100.0, signals_cache=cache["signals"])
    d = discover(load_job(r.job_path), r.log, signals=cache["signals"][str(r.job_path)])
    assert [e.name for e in d.effects] == []
    said = [n for n in d.notes if "runout not applicable" in n]
    assert said and "cannot show once-per-revolution content" in said[0], d.notes


def test_runout_at_1_khz_null_run_names_nothing(cache):
    """A 1 kHz log of a run without runout (the other tool's flutes): runout's per-cut harmonics, fitted
    there, do not pass the selection: no effect is named."""
    r = make_run(cache["dir"] / "job1", 1, "none", rate_hz=1000.0, signals_cache=cache["signals"])
    d = discover(load_job(r.job_path), r.log, signals=cache["signals"][str(r.job_path)])
    assert [e.name for e in d.effects] == [], d.notes
    assert not any("runout not applicable" in n for n in d.notes), d.notes


@pytest.mark.parametrize("flutes", (2, 3, 4, 5))
def test_runout_chip_offsets_from_harmonics(flutes):
    """Per-flute radii r_j (an axis offset ρ at ψ plus grinding errors): the chip offsets δ_j = r_j − r_(j−1)
    held while flute j cuts make a staircase over the revolution; its Fourier coefficients a_k, b_k
    (k = 1 … N−1, by numerical integration on a fine grid) give back √(2·mean δ_j²), also from harmonics
    1 … N/2 only, and, for N ≥ 3 with no grinding error, ρ."""
    from millpost.discover.effects.runout import eccentricity, offsets
    rng = np.random.default_rng(flutes)
    theta = (np.arange(360 * flutes * 50) + 0.5) / (360 * flutes * 50) * 2 * np.pi
    harmonics = list(range(1, flutes))
    for grind in (0.0, 0.003):
        rho, psi = 0.006, rng.uniform(0, 2 * np.pi)
        r = rho * np.cos(psi - 2 * np.pi * np.arange(flutes) / flutes) + grind * rng.normal(size=flutes)
        delta = r - np.roll(r, 1)
        stair = delta[np.floor(theta * flutes / (2 * np.pi)).astype(int)]
        ab = np.array([2 * np.mean(stair * f(k * theta)) for k in harmonics for f in (np.cos, np.sin)])
        assert offsets(ab, flutes, harmonics)[0] == pytest.approx(np.sqrt(2 * np.mean(delta ** 2)), rel=1e-6)
        m = flutes // 2     # the harmonics above N/2 left out (beyond a log's reach): their mirrors stand in
        assert offsets(ab[:2 * m], flutes, harmonics[:m])[0] == pytest.approx(np.sqrt(2 * np.mean(delta ** 2)),
                                                                               rel=1e-6)
        if flutes >= 4:
            assert offsets(ab[:2], flutes, harmonics[:1])[0] is None
        if grind == 0.0:   # two flutes show only ρ·cos ψ
            rho_fit = eccentricity(ab, flutes, harmonics)[0]
            assert rho_fit is None if flutes == 2 else rho_fit == pytest.approx(rho, rel=1e-6)


def test_empty_registry_is_a_clear_error(monkeypatch):
    import millpost.discover.search as search
    from millpost.errors import MillpostError
    monkeypatch.setattr(search, "plugins", lambda group: {})
    with pytest.raises(MillpostError, match="no candidate effects are registered"):
        search.candidates()


def test_cli_end_to_end_reviewer_format(tmp_path, capsys):
    """Straight passes in a box, 100 Hz log with t_s, x/y/z, spindle_rpm, fx/fy/fz, spindle_power_W,
    nominal coefficients off: the CLI names the hidden inertia and the predictions file recomputes the
    JSON's held-out RMS."""
    r = make_run(tmp_path / "job", 7, "inertia")
    log_path = tmp_path / "run.csv"
    write_log(log_path, r.log)
    assert list(read_log(log_path).columns) == ["t_s", "x_mm", "y_mm", "z_mm", "spindle_rpm", "fx_N", "fy_N",
                                                "fz_N", "spindle_power_W"]
    out, pred, html = tmp_path / "out.json", tmp_path / "pred.csv", tmp_path / "report.html"
    assert main(["discover", str(r.job_path), "--log", str(log_path), "--json", str(out), "--predictions",
                 str(pred), "--report", str(html), "--write-model", str(tmp_path / "model")]) == 0
    s = json.loads(out.read_text())
    assert set(s) == {"effects", "ambiguous", "rms_before", "rms_after", "offset_s", "alignment", "notes"}
    assert [e["name"] for e in s["effects"]][:1] == ["inertia"]
    e = s["effects"][0]
    assert {"name", "params", "stderr", "channels", "rms_before", "rms_after", "ambiguous_with"} <= set(e)
    assert s["alignment"] == "position" and s["ambiguous"] == [] and e["ambiguous_with"] == []
    assert e["params"]["mass_kg"] == pytest.approx(r.truth["mass_kg"], rel=0.1)
    with open(pred, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == len(r.log)
    cols = {k: np.array([float(row[k]) for row in rows]) for k in rows[0]}
    held = cols["held_out"] == 1
    for c in ("fx_N", "fy_N", "fz_N", "spindle_power_W"):   # the JSON's held-out RMS, recomputed
        for kind in ("before", "after"):
            rms = np.sqrt(np.mean((cols[f"{c}_measured"] - cols[f"{c}_{kind}"])[held] ** 2))
            assert rms == pytest.approx(s[f"rms_{kind}"][c], rel=1e-4)
    assert raw_shrink(cols, ["fx_N", "fz_N"]) >= 0.6
    assert "<svg" in html.read_text()
    model = load_job(tmp_path / "model" / "job.toml")
    assert model.material.mechanistic is not None
    said = capsys.readouterr().err.splitlines()   # each file written is said once
    for name in ("material.toml", "machine.toml", "job.toml"):
        assert said.count(f"millpost: wrote {tmp_path / 'model' / name}") == 1, said


def test_umich_axis_friction_from_inertia_only():
    """Real drive currents (UMich SMART CNC, 10 Hz velocity, acceleration, current feedback): starting from
    an inertia-only axis model, discover names axis_friction and reaches the held-out R² of a hand fit of
    inertia + Coulomb + viscous on the same fitting rows."""
    folder = shared_data("milling-datasets", "umich_smart_cnc_subset")
    for exp in ("01", "02", "11"):
        with open(folder / f"experiment_{exp}.csv", newline="") as fh:
            data = list(csv.DictReader(fh))
        col = lambda n: np.array([float(r[n]) for r in data])  # noqa: E731
        v = np.column_stack([col(f"{a}_ActualVelocity") for a in "XYZ"])
        a = np.column_stack([col(f"{a}_ActualAcceleration") for a in "XYZ"])
        currents = {f"i{ax.lower()}_A": col(f"{ax}_CurrentFeedback") for ax in "XY"}
        rows = from_axis_arrays(np.arange(len(data)) * 0.1, v, a, currents)
        sel = select(rows, {}, candidates())
        assert [e.name for e in sel.effects][:1] == ["axis_friction"], (exp, sel.scores)
        friction = sel.effects[0].params_
        assert all(v > 0 for v in friction.values()), (exp, friction)   # friction opposes the motion
        held = sel.block >= 0
        pred = sel.predict_after()
        for k, c in enumerate(currents):
            y = rows.measured[c]
            X = np.column_stack([a[:, k], np.sign(v[:, k]), v[:, k], np.ones(len(y))])
            beta, *_ = np.linalg.lstsq(X[sel.train], y[sel.train], rcond=None)
            ss = np.sum((y[held] - y[held].mean()) ** 2)
            r2_hand = 1 - np.sum((y[held] - X[held] @ beta) ** 2) / ss
            r2_disc = 1 - np.sum((y[held] - pred[c][held]) ** 2) / ss
            print(f"UMich {exp} {c}: held-out R² hand {r2_hand:.3f}, discover {r2_disc:.3f}")
            assert r2_disc >= r2_hand - 1e-3


def test_base_refit_keeps_cutting_coefficients_non_negative():
    """Data whose best unconstrained K_rc is negative: the refit puts K_rc on its bound 0, and the other
    parameters are then the ordinary least squares with K_rc's column left out (the bounded optimum
    when the gradient pushes K_rc below 0), computed here by numpy's lstsq."""
    from millpost.discover.model import design, solve
    from millpost.discover.rows import COEFS, Rows
    rng = np.random.default_rng(3)
    n = 400
    chans = ("fx_N", "spindle_power_W")
    cut = {c: np.abs(rng.normal(1.0, 0.5, (n, 6))) for c in ("fx_N", "fy_N", "fz_N", "spindle_power_W")}
    truth = np.array([600.0, -40.0, 250.0, 12.0, 9.0, 3.0])
    measured = {c: cut[c] @ truth + 5.0 + rng.normal(0, 2.0, n) for c in chans}
    rows = Rows(np.arange(n) * 0.01, measured, cut, {c: {"offset": np.ones(n)} for c in chans}, {})
    d = design(rows)
    train = np.ones(n, bool)
    sigma = {c: 1.0 for c in chans}
    fit = solve(d, rows, train, sigma)
    p = fit.params()
    assert p["Krc"] == 0.0 and min(p[k] for k in COEFS) >= 0.0
    X = np.vstack([d.X[c] for c in chans])
    y = np.concatenate([measured[c] for c in chans])
    keep = [k for k, name in enumerate(d.names) if name != "Krc"]
    beta, *_ = np.linalg.lstsq(X[:, keep], y, rcond=None)
    assert np.allclose([p[d.names[k]] for k in keep], beta, rtol=1e-6, atol=1e-6)
    grad = X[:, d.names.index("Krc")] @ (y - X[:, keep] @ beta)
    assert grad < 0      # K_rc pushed below 0: the bound is active
    assert fit.stderr()["Krc"] == 0.0 and fit.stderr()["Ktc"] > 0


def test_first_order_lag_of_a_ramp():
    """τ ẏ = x − y from rest at 0 with x = t: y = t − τ(1 − e^(−t/τ)) (closed form), sampled at 100 Hz."""
    from millpost.discover.effects.sensor_lag import first_order
    t = np.arange(0, 2.0, 0.01)
    for tau in (0.02, 0.15, 0.6):
        y = first_order(0.01, tau)(np.column_stack([t, 3 * t]))
        exact = t - tau * (1 - np.exp(-t / tau))
        assert np.allclose(y[:, 0], exact, atol=1e-12) and np.allclose(y[:, 1], 3 * exact, atol=1e-12)


def test_lag_input_bridges_the_rows_fits_leave_out():
    """Rows outside `use` are replaced by the straight line between the used rows around them (held at the
    ends), so the lag does not carry the forward model's known-wrong values into the rows after them."""
    from millpost.discover.effects.sensor_lag import bridge
    use = np.array([0, 1, 1, 0, 0, 1, 0, 0], bool)
    m = np.arange(8.0) ** 2
    assert np.allclose(bridge(use)(m), [1, 1, 4, 11, 18, 25, 25, 25])
    assert np.allclose(bridge(use)(np.column_stack([m, -m]))[:, 1], [-1, -1, -4, -11, -18, -25, -25, -25])
    assert bridge(None)(m) is m
