"""Wind and sensor errors against the formulas they come from (MIL-F-8785C's Dryden form and
1-cosine gust; a first-order Gauss–Markov GPS error), with values worked out by hand."""

import math

import numpy as np
import pytest

from dualpilot.plant.sensors import GpsError, GpsParams
from dualpilot.plant.wind import (
    DrydenTurbulence,
    GustParams,
    Gusts,
    Wind,
    WindParams,
    dryden_scales,
)


def test_dryden_scales_at_fifty_metres_moderate() -> None:
    # h = 50 m = 164.04 ft; 0.177 + 0.000823 h = 0.312007; W20 = 30 kt = 15.4333 m/s
    sigma, length = dryden_scales(50.0, 30 * 1852 / 3600)
    assert sigma == pytest.approx([2.45920, 2.45920, 1.54333], rel=1e-5)
    assert length == pytest.approx([202.2896, 202.2896, 50.0], rel=1e-5)


def test_dryden_scales_at_hundred_metres_light() -> None:
    # h = 328.08 ft; 0.177 + 0.000823 h = 0.447013; W20 = 15 kt
    sigma, length = dryden_scales(100.0, 15 * 1852 / 3600)
    assert sigma == pytest.approx([1.06488, 1.06488, 0.771667], rel=1e-5)
    assert length == pytest.approx([262.794, 262.794, 100.0], rel=1e-5)


def test_turbulence_level_sets_w20() -> None:
    assert WindParams(turbulence="severe").w20_mps == pytest.approx(45 * 0.514444, rel=1e-5)
    assert WindParams(turbulence="light", wind20_mps=3.0).w20_mps == 3.0
    with pytest.raises(ValueError, match="turbulence must be one of"):
        WindParams(turbulence="gale")  # type: ignore[arg-type]


def _autocorr(x: np.ndarray, lag: int) -> float:
    x = x - x.mean()
    return float(np.dot(x[:-lag], x[lag:]) / np.dot(x, x))


def test_dryden_variance_and_correlation_follow_the_spec() -> None:
    """Correlations of MIL-HDBK-1797's Dryden form: R_u = e^{−ξ}, R_v = R_w = e^{−ξ}(1 − ξ/2),
    ξ = Vτ/L; here V = 100 m/s so that L/V is 2.02 s (u, v) and 0.5 s (w)."""
    turb = DrydenTurbulence(50.0, 15.4333, np.random.default_rng(11))
    dt, air = 0.1, 100.0
    samples = np.vstack([turb.sample(10_000, dt, air) for _ in range(40)])
    sigma, length = turb.sigma, turb.length
    assert samples.std(axis=0) == pytest.approx(sigma, rel=0.05)
    for lag_s in (0.5, 1.0, 2.0, 4.0):
        lag = int(round(lag_s / dt))
        xi_uv, xi_w = air * lag_s / length[0], air * lag_s / length[2]
        assert _autocorr(samples[:, 0], lag) == pytest.approx(math.exp(-xi_uv), abs=0.03)
        assert _autocorr(samples[:, 1], lag) == pytest.approx(
            math.exp(-xi_uv) * (1 - xi_uv / 2), abs=0.03)
        assert _autocorr(samples[:, 2], lag) == pytest.approx(
            math.exp(-xi_w) * (1 - xi_w / 2), abs=0.03)
    # the components are independent
    assert abs(np.corrcoef(samples[:, 0], samples[:, 1])[0, 1]) < 0.05


def test_dryden_sampling_step_does_not_change_the_statistics() -> None:
    """Exact discretisation: the same process at 100 Hz has the same variance."""
    turb = DrydenTurbulence(50.0, 15.4333, np.random.default_rng(12))
    samples = np.vstack([turb.sample(100_000, 0.01, 100.0) for _ in range(4)])
    assert samples.std(axis=0) == pytest.approx(turb.sigma, rel=0.06)


def test_one_cosine_gust_shape() -> None:
    gusts = Gusts(GustParams(rate_per_min=0.0, peak_mps=6.0, half_length_m=40.0),
                  np.random.default_rng(0))
    gusts.active.append((0.0, np.array([0.0, 1.0, 0.0])))
    out = gusts.sample(100, 0.1, 10.0)  # x = 10 m/s · (k + 0.5)·0.1 s
    x = 10.0 * (np.arange(100) + 0.5) * 0.1
    expect = np.where(x <= 80.0, 3.0 * (1 - np.cos(np.pi * x / 40.0)), 0.0)
    assert out[:, 1] == pytest.approx(expect)
    assert out[:, 0] == pytest.approx(0.0) and out[:, 1].max() == pytest.approx(6.0, rel=1e-3)
    assert gusts.active == []  # over after 2·d_m = 80 m of air


def test_gust_arrivals_are_poisson() -> None:
    # 6 per minute for 2000 s: 200 expected (Poisson, σ ≈ 14); each a 0.1 s pulse at 100 m/s
    gusts = Gusts(GustParams(rate_per_min=6.0, peak_mps=1.0, half_length_m=5.0),
                  np.random.default_rng(4))
    blowing = np.concatenate([np.abs(gusts.sample(100, 0.01, 100.0)).max(axis=1) > 0
                              for _ in range(2000)])
    onsets = int(np.count_nonzero(blowing[1:] & ~blowing[:-1]) + blowing[0])
    assert 160 < onsets < 240


def test_mean_wind_direction() -> None:
    w = Wind(WindParams(wind_speed_mps=10.0, wind_dir_rad=math.pi / 2), 50.0,
             np.random.default_rng(0))
    assert w.sample(5, 0.01, np.zeros(3)) == pytest.approx(np.tile([0.0, 10.0, 0.0], (5, 1)))


def test_gps_error_is_gauss_markov_with_its_sigma_and_time_constant() -> None:
    params = GpsParams(gps_sigma_m=1.5, tau_s=10.0)
    errs = [GpsError(params, np.random.default_rng(s)) for s in range(4000)]
    start = np.array([e.error for e in errs])
    later = np.array([e.sample(50, 0.1)[-1] for e in errs])  # 5 s later
    # stationary: σ = 1.5 m horizontally, 1.5·0.40/0.21 = 2.857 m up
    assert later.std(axis=0) == pytest.approx([1.5, 1.5, 2.857], rel=0.05)
    # correlation over 5 s: e^{−5/10} = 0.6065
    for i in range(3):
        assert np.corrcoef(start[:, i], later[:, i])[0, 1] == pytest.approx(0.6065, abs=0.04)


def test_zero_gps_sigma_measures_exactly() -> None:
    gps = GpsError(GpsParams(), np.random.default_rng(0))
    p, v = np.array([1.0, 2.0, 3.0]), np.array([4.0, 5.0, 6.0])
    mp, mv = gps.measure(p, v)
    assert np.array_equal(mp, p) and np.array_equal(mv, v)
    assert not gps.sample(10, 0.01).any()


def test_dryden_spectra_follow_mil_f_8785c() -> None:
    """Welch PSDs of u and w against the spec's spatial spectra mapped to time, S(f) =
    Φ(2πf/V)·2π/V (one-sided, Hz): Φ_u = σ²(2L/π)/(1 + (LΩ)²), Φ_w = σ²(L/π)(1 + 3(LΩ)²)/
    (1 + (LΩ)²)², averaged over bands from 0.03 to 2 Hz."""
    from scipy.signal import welch

    turb = DrydenTurbulence(50.0, 15.4333, np.random.default_rng(21))
    fs, air = 20.0, 100.0
    samples = np.vstack([turb.sample(20_000, 1.0 / fs, air) for _ in range(40)])
    sigma, length = turb.sigma, turb.length
    f, psd = welch(samples, fs=fs, nperseg=4096, axis=0)
    omega = 2 * np.pi * f / air
    lu, lw = length[0], length[2]
    phi_u = sigma[0] ** 2 * (2 * lu / np.pi) / (1 + (lu * omega) ** 2)
    xw = (lw * omega) ** 2
    phi_w = sigma[2] ** 2 * (lw / np.pi) * (1 + 3 * xw) / (1 + xw) ** 2
    for lo, hi in ((0.03, 0.1), (0.1, 0.3), (0.3, 1.0), (1.0, 2.0)):
        band = (f >= lo) & (f < hi)
        for col, phi in ((0, phi_u), (2, phi_w)):
            expect = float(np.mean(phi[band] * 2 * np.pi / air))
            assert float(np.mean(psd[band, col])) == pytest.approx(expect, rel=0.06)
