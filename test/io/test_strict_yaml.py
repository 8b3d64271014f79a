"""The one YAML loader: alias bombs, duplicate keys and YAML 1.2 numbers, in every place a
YAML text is read (scene files through `scenes`/`simulate`/gyro_sim, QoS metadata, bag
metadata.yaml)."""

import resource
import subprocess
import sys
import textwrap

import pytest

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.qos import parse_qos_profiles
from gyro_attitude.io.scene_file import load_scene
from gyro_attitude.io.strict_yaml import load_yaml

SCENE = textwrap.dedent("""\
    description: IMU at rest
    seed: 3
    rate_hz: 100.0
    duration_s: 1.0
    earth: {latitude_deg: 45.0}
    motion: {type: stationary}
    """)


def alias_bomb(key: str = "description") -> str:
    """A ~500-byte document whose ``key`` stands for 9**8 strings (nine references per level)."""
    lines = ['a0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        refs = ",".join([f"*a{i - 1}"] * 9)
        lines.append(f"a{i}: &a{i} [{refs}]")
    body = "\n".join(lines)
    return body + f"\n{key}: *a8\n"


def test_alias_is_refused_with_its_line_before_any_value_is_built():
    text = alias_bomb()
    assert len(text) < 700
    with pytest.raises(ValueError, match=r"^bomb\.yaml: not valid YAML: .*aliases \(\*a0\) are "
                                         r"not accepted.* line 2"):
        load_yaml(text, "bomb.yaml")
    # merge keys need an alias: refused too; an anchor alone is harmless
    with pytest.raises(ValueError, match="aliases"):
        load_yaml("base: &b {x: 1}\nother:\n  <<: *b\n")
    assert load_yaml("base: &b {x: 1}\n") == {"base": {"x": 1}}


def test_duplicate_keys_are_refused_naming_the_key_and_line():
    with pytest.raises(ValueError, match=r"duplicate key 'seed'.* line 3"):
        load_yaml("seed: 1\nrate_hz: 2\nseed: 2\n")
    with pytest.raises(ValueError, match=r"duplicate key 'latitude_deg'"):
        load_yaml("earth: {latitude_deg: 1, latitude_deg: 2}\n")
    assert load_yaml("a: {x: 1}\nb: {x: 1}\n") == {"a": {"x": 1}, "b": {"x": 1}}


@pytest.mark.parametrize("text, value", [
    ("1.0e6", 1.0e6), ("1e6", 1.0e6), ("-2.5E-3", -2.5e-3), ("+1.5e+2", 150.0), (".5", 0.5),
    ("3.", 3.0)])
def test_numbers_with_an_exponent_are_read_as_numbers(text, value):
    got = load_yaml(f"v: {text}\n")["v"]
    assert isinstance(got, float) and got == value


@pytest.mark.parametrize("text, value", [
    ("42", 42), ("0x10", 16), ("true", True), ("abc", "abc"), ("'1.0e6'", "1.0e6"),
    ("1.2.3", "1.2.3"), ("1e", "1e"), (".inf", float("inf"))])
def test_other_scalars_are_read_as_before(text, value):
    got = load_yaml(f"v: {text}\n")["v"]
    assert got == value and type(got) is type(value)


def _run_limited(code: str, seconds: int = 60) -> subprocess.CompletedProcess:
    """Run ``code`` in a child with 1 GB of address space more than it starts with."""
    def limit():
        resource.setrlimit(resource.RLIMIT_AS, (3 << 30, 3 << 30))
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          timeout=seconds, preexec_fn=limit)


@pytest.mark.parametrize("key", ["description", "seed"])
@pytest.mark.parametrize("command", ["scenes", "simulate"])
def test_alias_bomb_scene_is_one_line_and_exit_1_in_the_commands(tmp_path, key, command):
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text(SCENE.replace(f"{key}:", "old_" + key + ":") + alias_bomb(key)
                    .replace("a0:", "x0:"), encoding="utf-8")
    # keys a0..a8 are unknown to the schema, but the alias is refused before that
    argv = [command, str(bomb)] if command == "scenes" else \
        [command, str(bomb), "--duration", "1", "--out", str(tmp_path / "o.mcap")]
    r = _run_limited(f"from gyro_attitude.cli import main; raise SystemExit(main({argv!r}))")
    assert r.returncode == 1, r
    assert len(r.stderr.splitlines()) == 1 and "aliases" in r.stderr, r.stderr
    assert "bomb.yaml" in r.stderr and "Traceback" not in r.stderr
    assert not (tmp_path / "o.mcap").exists()


def test_listing_scenes_with_a_bomb_among_them_stays_small(tmp_path, monkeypatch):
    (tmp_path / "bomb.yaml").write_text(alias_bomb(), encoding="utf-8")
    from gyro_attitude.io import scene_file

    monkeypatch.setattr(scene_file, "scene_directories", lambda: [tmp_path])
    [(name, desc)] = scene_file.list_scenes()
    assert name == "bomb" and desc.startswith("(invalid: ") and "aliases" in desc
    assert len(desc) < 400


def test_scene_file_duplicate_key_and_exponent_number(tmp_path):
    p = tmp_path / "dup.yaml"
    p.write_text(SCENE + "seed: 4\n", encoding="utf-8")
    with pytest.raises(ValueError, match=r"^.*dup\.yaml: not valid YAML: duplicate key 'seed'"):
        load_scene(str(p))
    p.write_text(SCENE.replace("rate_hz: 100.0", "rate_hz: 1.0e2"), encoding="utf-8")
    assert load_scene(str(p)).rate_hz == 100.0


def test_qos_metadata_alias_bomb_and_duplicates_are_refused():
    with pytest.raises(ValueError, match="aliases"):
        parse_qos_profiles(alias_bomb("- history"))
    with pytest.raises(ValueError, match="duplicate key 'depth'"):
        parse_qos_profiles("- history: keep_last\n  depth: 10\n  depth: 11\n")


def test_seed_may_be_left_out_of_a_scene_when_given_on_the_command_line(tmp_path, capsys):
    p = tmp_path / "noseed.yaml"
    p.write_text(SCENE.replace("seed: 3\n", ""), encoding="utf-8")
    out = tmp_path / "o.mcap"
    assert cli_main(["simulate", str(p), "--duration", "0.1", "--out", str(out),
                     "--seed", "7"]) == 0
    assert "seed 7" in capsys.readouterr().out
    assert load_scene(str(p), seed=7).seed == 7
    with pytest.raises(ValueError, match=r"noseed\.yaml: seed: "):
        load_scene(str(p))
    assert cli_main(["simulate", str(p), "--duration", "0.1", "--out",
                     str(tmp_path / "p.mcap")]) == 1
    assert "seed" in capsys.readouterr().err


def test_what_the_package_writes_reads_back_without_aliases():
    from gyro_attitude.io.strict_yaml import dump_yaml

    shared = [1.0e-6, 2.0e-6, 3.0e6]
    text = dump_yaml({"gyro": {"bias": shared}, "accelerometer": {"bias": shared}})
    assert "&" not in text and "*" not in text
    assert load_yaml(text) == {"gyro": {"bias": shared}, "accelerometer": {"bias": shared}}
