"""Scene files: lookup, loading, refusal messages, the shipped scenes and `gyro-attitude scenes`."""

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

from gyro_attitude.cli import main as cli_main
from gyro_attitude.core.scene import SceneSimulator
from gyro_attitude.io import scene_file
from gyro_attitude.io.scene_file import list_scenes, load_scene

SHIPPED = ("lab_bench", "ship", "aircraft_turn", "coning", "spinning_projectile",
           "free_gyro_drift", "rate_gyro_step")
SOURCE_SCENES = Path(__file__).resolve().parents[2] / "config" / "scenes"
OMEGA_IE = 7.292115e-5


def test_every_shipped_scene_is_listed_with_a_description_and_a_seed():
    listed = dict(list_scenes())
    for name in SHIPPED:
        assert listed.get(name), f"{name} missing or without description"
        raw = yaml.safe_load((SOURCE_SCENES / f"{name}.yaml").read_text(encoding="utf-8"))
        assert isinstance(raw["seed"], int) and raw["description"].strip()


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_loads_and_runs(name):
    spec = load_scene(name)
    assert spec.name == name
    sim = SceneSimulator(spec, spec.rate_hz)
    b = sim.next_block(64)
    assert b.t_ns.shape == (64,) and np.all(np.diff(b.t_ns) > 0)
    assert np.all(np.isfinite(b.omega_ib_b)) and np.all(np.isfinite(b.truth_q_nb))
    assert f"motion.{spec.motion_type}" in sim.effects_run
    assert (b.specific_force_b is not None) == ("accelerometer" in spec.source)
    assert (b.gimbal is not None) == (name == "free_gyro_drift")


def test_lab_bench_truth_is_earth_rate_facing_north():
    spec = load_scene("lab_bench")
    b = SceneSimulator(spec, 100.0).next_block(10)
    lat = np.radians(45.0)
    # Level, nose north: body x = North, y = West, z = Up.
    expect = [OMEGA_IE * np.cos(lat), 0.0, OMEGA_IE * np.sin(lat)]
    assert np.abs(b.truth_omega_ib_b - expect).max() < 1e-15


def test_coning_scene_file_is_the_design_reference_case():
    spec = load_scene("coning")
    b = SceneSimulator(spec, spec.rate_hz).next_block(500)
    t = b.t_ns / 1e9
    a, om = np.radians(1.0), 2 * np.pi * 10.0
    w = np.stack((np.full_like(t, -2 * om * np.sin(a / 2) ** 2), -om * np.sin(a) * np.sin(om * t),
                  om * np.sin(a) * np.cos(om * t)), 1)
    assert np.abs(b.omega_ib_b - w).max() < 1e-13


def test_load_by_path_and_errors_name_file_and_key(tmp_path):
    good = yaml.safe_load((SOURCE_SCENES / "lab_bench.yaml").read_text(encoding="utf-8"))
    p = tmp_path / "mine.yaml"
    p.write_text(yaml.safe_dump(good), encoding="utf-8")
    assert load_scene(str(p)).name == "mine"
    good["earth"]["latitude_deg"] = 100.0
    p.write_text(yaml.safe_dump(good), encoding="utf-8")
    with pytest.raises(ValueError, match=r"mine\.yaml: earth\.latitude_deg: must be <= 90"):
        load_scene(str(p))
    p.write_text("earth: [unclosed\n", encoding="utf-8")
    with pytest.raises(ValueError, match="not valid YAML"):
        load_scene(str(p))
    p.write_text("- a\n- b\n", encoding="utf-8")
    with pytest.raises(ValueError, match="must be a YAML mapping"):
        load_scene(str(p))
    with pytest.raises(ValueError, match="scene file not found"):
        load_scene(str(tmp_path / "absent.yaml"))
    with pytest.raises(ValueError, match=r"unknown scene 'atlantis' \(shipped scenes: .*coning"):
        load_scene("atlantis")


def test_installed_share_directory_is_searched(tmp_path, monkeypatch):
    share = tmp_path / "share" / "gyro_attitude" / "config" / "scenes"
    share.mkdir(parents=True)
    (share / "only_installed.yaml").write_text(
        (SOURCE_SCENES / "coning.yaml").read_text(encoding="utf-8"), encoding="utf-8")
    monkeypatch.setattr(sys, "prefix", str(tmp_path))
    assert share in scene_file.scene_directories()
    assert scene_file.find_scene_file("only_installed") == share / "only_installed.yaml"
    assert "only_installed" in dict(list_scenes())


def test_lookup_works_without_an_ament_environment(monkeypatch):
    monkeypatch.delenv("AMENT_PREFIX_PATH", raising=False)
    assert scene_file.find_scene_file("ship").name == "ship.yaml"
    assert "coning" in dict(list_scenes())


def test_scenes_command_lists_and_prints(capsys):
    assert cli_main(["scenes", "--check"]) == 0
    out = capsys.readouterr().out
    for name in SHIPPED:
        assert any(line.startswith(name + " ") for line in out.splitlines())
    assert cli_main(["scenes", "ship"]) == 0
    assert capsys.readouterr().out == (SOURCE_SCENES / "ship.yaml").read_text(encoding="utf-8")
    assert cli_main(["scenes", "atlantis"]) == 1
    assert "unknown scene" in capsys.readouterr().err


@pytest.mark.parametrize(
    "content, message",
    [
        (b"\x7fELF\x02\x01\x01\x00\xff\xfe binary", r"not a scene file: not UTF-8 text \(byte 0xff"),
        (b"root:x:0:0:root:/root:/bin/bash\n", r"a scene must be a YAML mapping, got str"),
        (b"", r"a scene must be a YAML mapping, got NoneType"),
        (b"description: [unclosed\n", r"not valid YAML"),
        (b"[" * 5000 + b"]" * 5000, r"not a scene file: YAML nested too deeply|not valid YAML"),
        (b"description: x\nseed: 1\nrate_hz: 1.0e+12\nearth: {latitude_deg: 1}\n"
         b"motion: {type: stationary}\n", r"bad\.yaml: rate_hz: must be <= 1e\+06"),
    ],
)
def test_scenes_command_refuses_a_file_that_is_not_a_valid_scene(tmp_path, capsys, content,
                                                                  message):
    p = tmp_path / "bad.yaml"
    p.write_bytes(content)
    assert cli_main(["scenes", str(p)]) == 1
    out, err = capsys.readouterr()
    assert out == ""
    assert len(err.splitlines()) == 1 and err.startswith("gyro-attitude scenes: error: ")
    assert re.search(message, err), err


def test_scene_file_size_is_bounded(tmp_path):
    p = tmp_path / "huge.yaml"
    p.write_bytes(b"#" * (scene_file.MAX_SCENE_FILE_BYTES + 1))
    with pytest.raises(ValueError, match=r"too large for a scene file"):
        load_scene(str(p))
    with pytest.raises(ValueError, match=r"cannot read"):
        scene_file.read_scene_text(tmp_path / "missing.yaml")


@pytest.mark.parametrize("path", ["/bin/ls", "/etc/passwd"])
def test_scenes_command_on_system_files_is_one_line_and_nonzero(path):
    if not Path(path).is_file():
        pytest.skip(f"{path} not on this machine")
    code = f"from gyro_attitude.cli import main; raise SystemExit(main(['scenes', {path!r}]))"
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1, r
    assert r.stdout == ""
    assert len(r.stderr.splitlines()) == 1 and r.stderr.startswith(
        "gyro-attitude scenes: error: /"), r.stderr
    assert "Traceback" not in r.stderr
