"""allan --kalibr-out: fitted terms in Kalibr's imu.yaml convention, and a scene that takes the file back."""

import numpy as np
import pytest
import yaml

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.imu_fast import read_imu_arrays
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.offline.simulate import simulate

N_GYRO, K_GYRO = 1.0e-3, 2.0e-5  # rad/s/√Hz, rad/s²/√Hz
N_ACC, K_ACC = 2.0e-3, 1.0e-4  # m/s²/√Hz, m/s³/√Hz
RATE = 100.0


@pytest.fixture(scope="module")
def noisy_record(tmp_path_factory):
    d = tmp_path_factory.mktemp("kalibr")
    scene = {"description": "white noise and random walk", "seed": 5, "rate_hz": RATE,
             "start_time_ns": 10**9, "earth": {"latitude_deg": 45.0},
             "motion": {"type": "stationary"},
             "gyro": {"errors": {"arw_rad_sqrt_s": N_GYRO, "rate_random_walk": K_GYRO}},
             "accelerometer": {"errors": {"vrw_m_s_sqrt_s": N_ACC,
                                          "acceleration_random_walk": K_ACC}}}
    (d / "s.yaml").write_text(yaml.safe_dump(scene))
    rec = d / "rec.mcap"
    simulate(str(d / "s.yaml"), 4000.0, rec, publish_truth=False)
    return d, rec


def test_kalibr_out_holds_the_fitted_densities_and_random_walks(noisy_record, capsys):
    d, rec = noisy_record
    out = d / "imu.yaml"
    assert cli_main(["allan", str(rec), "--kalibr-out", str(out), "--force"]) == 0
    text = out.read_text()
    assert "sigma_d = noise_density * sqrt(f)" in text  # the convention is stated
    k = yaml.safe_load(text)
    assert k["rostopic"] == "/imu/data_raw" and k["update_rate"] == pytest.approx(RATE)
    # continuous-time values, not per sample: a per-sample σ would be 10x (√100 Hz) larger
    assert k["gyroscope_noise_density"] == pytest.approx(N_GYRO, rel=0.05)
    assert k["accelerometer_noise_density"] == pytest.approx(N_ACC, rel=0.05)
    assert k["gyroscope_random_walk"] == pytest.approx(K_GYRO, rel=0.5)
    assert k["accelerometer_random_walk"] == pytest.approx(K_ACC, rel=0.5)


def test_a_scene_takes_the_kalibr_file_and_simulates_its_per_sample_noise(noisy_record, tmp_path):
    d, rec = noisy_record
    imu_yaml = tmp_path / "imu.yaml"
    assert cli_main(["allan", str(rec), "--kalibr-out", str(imu_yaml)]) == 0
    k = yaml.safe_load(imu_yaml.read_text())
    scene = {"description": "from kalibr", "seed": 2, "rate_hz": 400.0, "start_time_ns": 10**9,
             "earth": {"latitude_deg": 45.0}, "motion": {"type": "stationary"},
             "kalibr_imu": "imu.yaml", "accelerometer": {}}
    (tmp_path / "k.yaml").write_text(yaml.safe_dump(scene))
    spec = load_scene(str(tmp_path / "k.yaml"))
    assert np.all(spec.gyro_errors.noise_density == k["gyroscope_noise_density"])
    assert np.all(spec.gyro_errors.rate_random_walk == k["gyroscope_random_walk"])
    assert np.all(spec.accel_errors.noise_density == k["accelerometer_noise_density"])
    assert np.all(spec.accel_errors.rate_random_walk == k["accelerometer_random_walk"])
    # Kalibr's discretization: per sample at 400 Hz the white noise is density · √400
    out = tmp_path / "k.mcap"
    simulate(str(tmp_path / "k.yaml"), 50.0, out, publish_truth=False)
    w = read_imu_arrays(out, "imu/data_raw").angular_velocity
    per_sample = np.std(np.diff(w, axis=0), axis=0) / np.sqrt(2.0)
    np.testing.assert_allclose(per_sample, k["gyroscope_noise_density"] * np.sqrt(400.0),
                               rtol=0.03)


def test_kalibr_file_clashing_with_the_scene_or_broken_is_one_line(noisy_record, tmp_path, capsys):
    d, rec = noisy_record
    (tmp_path / "imu.yaml").write_text("gyroscope_noise_density: 1.0e-3\n")
    scene = {"description": "x", "seed": 2, "earth": {"latitude_deg": 45.0},
             "motion": {"type": "stationary"}, "kalibr_imu": "imu.yaml"}
    (tmp_path / "a.yaml").write_text(yaml.safe_dump(scene))
    with pytest.raises(ValueError, match="gyroscope_random_walk is missing"):
        load_scene(str(tmp_path / "a.yaml"))
    (tmp_path / "imu.yaml").write_text("gyroscope_noise_density: 1.0e-3\n"
                                       "gyroscope_random_walk: 1.0e-5\n")
    scene["gyro"] = {"errors": {"arw": "0.1 deg/sqrt(h)"}}
    (tmp_path / "b.yaml").write_text(yaml.safe_dump(scene))
    with pytest.raises(ValueError, match=r"gyro\.errors\.arw: given by the scene and by kalibr_imu"):
        load_scene(str(tmp_path / "b.yaml"))
    scene["kalibr_imu"] = "missing.yaml"
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(scene))
    assert cli_main(["simulate", str(tmp_path / "c.yaml"), "--duration", "1", "--out",
                     str(tmp_path / "o.mcap")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "kalibr_imu" in err[0] and "no such file" in err[0]
