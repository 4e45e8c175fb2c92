"""The status of a fit without sigmas says only what it tested (sysid/assess/fit_status.h): each
sensor's residuals against the noise its log shows; where that noise cannot be estimated, a
warning that the model check was not possible, with the % fit.

Data: the pendulum experiment's simulated log (3 sequences of 2000 steps; truth damping 0.08,
frictionloss 0.03, bob_mass 1.2; noise sigma 0.001 rad (angle) and 0.01 rad/s (rate); start 0.2,
0.01, 0.8), no sigmas given to the fit.
"""

import mjsysid
from test_fit_api import PARAMETERS, frames, sequences_of  # noqa: F401 (a fixture)

NOT_POSSIBLE = "model check not possible"


def test_a_good_fit_without_sigmas_is_checked_against_the_logs_noise(root, frames):  # noqa: F811
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS, sequences_of(frames))
    assert result.status == "converged"
    # the residuals are the log's noise: about 1 x its estimate, both sensors tested
    assert set(result.sensor_noise_ratio) == {"angle", "rate"}
    for sensor, ratio in result.sensor_noise_ratio.items():
        assert 0.8 < ratio < 1.25, (sensor, ratio)
    assert not any(NOT_POSSIBLE in w or "model mismatch" in w for w in result.warnings)


def test_unexplained_data_without_sigmas_is_a_model_mismatch(root, frames):  # noqa: F811
    # bob_mass alone: damping and friction loss stay at the model's 0.05 and 0.01 (truth 0.08,
    # 0.03); the residuals are far above the log's noise (angle 24 x) at a % fit below 90
    result = mjsysid.fit(str(root / "models/pendulum.xml"), PARAMETERS[2:], sequences_of(frames))
    assert result.status == "model_mismatch" and not result.intervals_valid
    assert result.sensor_noise_ratio["angle"] > 5
    assert any(w.startswith("model mismatch: the fit does not explain the data") and
               "sensors without a sigma" in w for w in result.warnings)


def test_without_a_noise_estimate_the_status_says_the_check_was_not_possible(
        root, frames):  # noqa: F811
    # 9 samples per sequence: 7 triples of consecutive samples, fewer than the 8 a noise estimate
    # needs (sysid/assess/noise_estimate.h), and friction loss left at the model's 0.01 (truth
    # 0.03): the solver converges, nothing can test the model; a warning says so, with the % fit
    # (before, nothing said it: status converged, intervals valid, no warning)
    short = [dict(s, time=s["time"][:9], ctrl=s["ctrl"][:9], measured=s["measured"][:9])
             for s in sequences_of(frames)]
    result = mjsysid.fit(str(root / "models/pendulum.xml"), [PARAMETERS[0], PARAMETERS[2]],
                         short)
    assert result.status == "converged"
    assert result.sensor_noise_ratio == {}
    (warning,) = [w for w in result.warnings if w.startswith(NOT_POSSIBLE)]
    assert "for angle (% fit " in warning and ", rate (% fit " in warning
    assert "the status does not say whether the model explains these sensors" in warning
    # the angle's % fit is far below 90 (the fit of 9 samples leaves most of it)
    assert "a % fit below 90 leaves a visible part of the motion unexplained" in warning
    fits = [f.fit_final for s in result.sequences for f in s.channel_fits if f.channel == "angle"]
    assert min(fits) < 90
    # with a sigma for a sensor it is checked (chi-square), and only the other one is named
    with_sigma = mjsysid.fit(str(root / "models/pendulum.xml"), [PARAMETERS[0], PARAMETERS[2]],
                             short, options={"sensor_sigmas": {"rate": 0.01}})
    (warning,) = [w for w in with_sigma.warnings if w.startswith(NOT_POSSIBLE)]
    assert "for angle (% fit " in warning and "rate (% fit" not in warning


def test_the_experiment_runner_says_so_too(pendulum, tmp_path):
    # the same verdict through the runner of `sysid fit` (fit_experiment): the pendulum experiment
    # without its sensors' sigmas, 9 steps per sequence
    text = pendulum.read_text()
    sigmas = "sensors:\n  - {name: angle, sigma: 0.001}\n  - {name: rate, sigma: 0.01}\n"
    assert sigmas in text and "steps: 2000" in text
    pendulum.write_text(text.replace(sigmas, "").replace("steps: 2000", "steps: 9"))
    mjsysid.simulate(str(pendulum))
    fit = mjsysid.fit_experiment(str(pendulum), out=str(tmp_path / "out"))
    assert fit.status == "converged" and fit.exit_code == 0
    assert any(w.startswith(NOT_POSSIBLE) and "for angle (% fit " in w for w in fit.warnings)
    back = mjsysid.read_result(str(tmp_path / "out"))
    assert any(w.startswith(NOT_POSSIBLE) for w in back.warnings)
