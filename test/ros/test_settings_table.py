"""The estimator settings are declared once (core/attitude/settings.py): the node's parameters,
replay's flags, the YAML file and the table of docs/settings.md all come from that one table."""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import pytest
import yaml

from gyro_attitude.commands.estimator_flags import add_estimator_flags, config_from_args
from gyro_attitude.core.attitude.modes import Aiding, GyroBiasMode
from gyro_attitude.core.attitude.settings import (
    SETTINGS,
    Setting,
    SettingError,
    StreamConfig,
    yaml_lines,
)
from gyro_attitude.io import settings_docs
from gyro_attitude.ros.attitude_integrator_node import parameter_specs
from gyro_attitude.ros.params import check_value

REPO = Path(__file__).resolve().parents[2]

NEW = Setting("zz_new_threshold", 0.25, "a setting added for this test", "m/s", 0.0, 2.0,
              runtime=True, group="input")


def test_a_setting_added_in_one_place_is_a_parameter_a_flag_and_a_yaml_line():
    table = (*SETTINGS, NEW)
    spec = {s.name: s for s in parameter_specs(table)}["zz_new_threshold"]
    assert spec.default == 0.25 and spec.runtime and (spec.low, spec.high) == (0.0, 2.0)
    assert "a setting added for this test [m/s]" in spec.description
    assert check_value(spec, 3.0) is not None and check_value(spec, 1.0) is None

    parser = argparse.ArgumentParser()
    parser.error = lambda message: (_ for _ in ()).throw(ValueError(message))
    add_estimator_flags(parser, table)
    args = parser.parse_args(["--zz-new-threshold", "1.5"])
    assert args.setting__zz_new_threshold == 1.5
    with pytest.raises((ValueError, SystemExit)):
        parser.parse_args(["--zz-new-threshold", "7"])

    assert any(line.strip().startswith("zz_new_threshold: 0.25  # a setting added")
               for line in yaml_lines(settings=table))


def test_yaml_and_settings_doc_blocks_are_the_table():
    for path, text in settings_docs.rendered(REPO).items():
        assert path.read_text() == text, (
            f"{path} drifted from core/attitude/settings.py: run "
            "python -m gyro_attitude.io.settings_docs")


def test_yaml_file_holds_every_setting_at_its_default():
    params = yaml.safe_load((REPO / "config/attitude_integrator.yaml").read_text())[
        "attitude_integrator"]["ros__parameters"]
    node_names = {s.name for s in parameter_specs()}
    assert set(params) == node_names
    defaults = StreamConfig().values()
    for s in SETTINGS:
        value = params[s.name]
        assert value == defaults[s.name] or (isinstance(value, list) and
                                             value == list(defaults[s.name])), s.name


def test_node_parameters_and_replay_flags_have_the_same_names():
    parser = argparse.ArgumentParser()
    add_estimator_flags(parser)
    flags = {o for a in parser._actions for o in a.option_strings}
    params = {s.name for s in parameter_specs()}
    for s in SETTINGS:
        assert s.name in params and "--" + s.name.replace("_", "-") in flags


def test_replay_shorthands_set_the_settings_they_stand_for():
    parser = argparse.ArgumentParser()
    add_estimator_flags(parser)
    cfg = config_from_args(parser.parse_args(["--gyro-bias", "0.1,0,-0.2", "--latitude-deg",
                                              "45", "--initial-attitude", "level"]))
    assert cfg.gyro_bias is GyroBiasMode.PARAMETER and cfg.gyro_bias_rad_s == (0.1, 0.0, -0.2)
    assert cfg.latitude_rad == pytest.approx(math.pi / 4) and cfg.levelling
    cfg = config_from_args(parser.parse_args(["--gyro-bias", "none", "--aiding", "GRAVITY"]))
    assert cfg.gyro_bias is GyroBiasMode.NONE and cfg.aiding is Aiding.GRAVITY


@pytest.mark.parametrize(("name", "word"), [("gyro_bias", "automatic"), ("aiding", "mag"),
                                            ("frame", "ned"), ("heading_source", "compass")])
def test_a_mode_is_parsed_once_and_the_refusal_names_setting_and_words(name, word):
    with pytest.raises(SettingError) as exc:
        StreamConfig(**{name: word})
    assert exc.value.setting == name
    allowed = next(s for s in SETTINGS if s.name == name).choices
    assert str(exc.value).startswith(f"{name} must be one of ")
    assert all(m.value in str(exc.value) for m in allowed)
