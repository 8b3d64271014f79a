"""``gyro-attitude montecarlo``: a NEES outside its band is explained on the spot (which of the
scene's gyro terms the reported covariance leaves out, or over-counts), in the table's output and
in the JSON; a scene whose terms the covariance models has its NEES inside the band, no note.

The explanations were checked against scene variants (docs/montecarlo.md): lab_bench without its
bias instability and rate random walk, aircraft_turn without quantization and ship without bias
instability all come inside the band with default settings."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

from gyro_attitude.cli import main as cli_main

os.environ.setdefault("AMENT_PREFIX_PATH", sys.prefix)
SCENES = Path(__file__).resolve().parents[2] / "config" / "scenes"


def _mc(capsys, tmp_path, scene, *extra):
    # the gyro's error terms alone: no accelerometer aiding (the notes explain gyro terms)
    js = tmp_path / "mc.json"
    assert cli_main(["montecarlo", str(scene), "--runs", "20", "--duration", "30", "--rate",
                     "100", "--workers", "1", "--no-progress", "--json", str(js),
                     "--aiding", "none", *extra]) == 0
    out = capsys.readouterr().out
    return out, json.loads(js.read_text())["statistics"][0]["nees"]["final"]


def test_lab_bench_nees_above_its_band_names_bias_instability_and_rate_random_walk(
        tmp_path, capsys):
    out, final = _mc(capsys, tmp_path, "lab_bench")
    assert final["within"] is False and final["outside"] == "above"
    notes = [ln for ln in out.splitlines() if ln.startswith("note: lab_bench")]
    assert len(notes) == 1 and "too small" in notes[0], out
    assert "bias instability" in notes[0] and "rate random walk" in notes[0]
    assert any("bias instability" in e for e in final["explanation"])


def test_quantization_counted_as_white_noise_explains_a_nees_below_its_band(tmp_path, capsys):
    out, final = _mc(capsys, tmp_path, "aircraft_turn")
    assert final["within"] is False and final["outside"] == "below"
    assert "too large" in out and "quantization" in out, out


def test_a_scene_whose_terms_the_covariance_models_has_no_note(tmp_path, capsys):
    """aircraft_turn without its quantization: white noise only, NEES inside the band."""
    text = (SCENES / "aircraft_turn.yaml").read_text()
    scene = tmp_path / "white_only.yaml"
    scene.write_text(text.replace("quantization_rad: 1.0e-6", ""))
    out, final = _mc(capsys, tmp_path, scene)
    assert final["within"] is True and "explanation" not in final
    assert "note:" not in out, out
