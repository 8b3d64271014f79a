"""Scene files: lookup of the shipped scenes by name, and safe reading and validation of scene YAML.

A scene is found by path (any existing file) or by name (``<name>.yaml`` in the scene
directories, searched in this order):

1. ``config/scenes`` of the source tree next to the package, when running from a checkout
   (an installed package has no such directory next to it, so this never shadows an
   install with anything but the checkout being worked on);
2. ``<share>/gyro_attitude/config/scenes`` with ``<share>`` from
   ``ament_index_python.packages.get_package_share_directory`` (imported lazily; skipped when
   not importable or the package is not indexed);
3. ``<sys.prefix>/share/gyro_attitude/config/scenes`` (pip/venv installs).
"""

from __future__ import annotations

import sys
from pathlib import Path

from gyro_attitude.core.scene import SceneSpec
from gyro_attitude.io.strict_yaml import load_yaml

__all__ = [
    "scene_directories",
    "find_scene_file",
    "load_scene",
    "list_scenes",
    "read_scene_dict",
    "read_scene_text",
    "validate_scene_text",
    "MAX_SCENE_FILE_BYTES",
]

PACKAGE = "gyro_attitude"
#: Largest scene file read (bytes): the shipped scenes are about 1 kB.
MAX_SCENE_FILE_BYTES = 1 << 20


def scene_directories() -> list[Path]:
    """Existing scene directories in search order (see module docstring), without repeats."""
    candidates = [Path(__file__).resolve().parents[2] / "config" / "scenes"]
    try:
        from ament_index_python.packages import (
            PackageNotFoundError,
            get_package_share_directory,
        )

        try:
            candidates.append(Path(get_package_share_directory(PACKAGE)) / "config" / "scenes")
        except (PackageNotFoundError, LookupError, ValueError, OSError):
            pass  # not indexed, or AMENT_PREFIX_PATH unset (OSError): use the fallbacks
    except ImportError:
        pass
    candidates.append(Path(sys.prefix) / "share" / PACKAGE / "config" / "scenes")
    out: list[Path] = []
    for c in candidates:
        if c.is_dir() and c.resolve() not in [o.resolve() for o in out]:
            out.append(c)
    return out


def find_scene_file(name_or_path: str) -> Path:
    """Path of a scene given as a file path or a shipped scene name; ``ValueError`` if none."""
    p = Path(name_or_path)
    if p.is_file():
        return p
    if p.suffix in (".yaml", ".yml") or "/" in str(name_or_path):
        raise ValueError(f"scene file not found: {name_or_path}")
    dirs = scene_directories()
    for d in dirs:
        f = d / f"{name_or_path}.yaml"
        if f.is_file():
            return f
    known = ", ".join(name for name, _ in list_scenes()) or "none"
    raise ValueError(f"unknown scene {name_or_path!r} (shipped scenes: {known}; "
                     f"searched {', '.join(map(str, dirs)) or 'no scene directory'})")


def read_scene_text(path: Path) -> str:
    """The text of a scene file; ``ValueError`` naming the file unless it is a readable UTF-8
    text file of at most :data:`MAX_SCENE_FILE_BYTES`."""
    try:
        size = Path(path).stat().st_size
        if size > MAX_SCENE_FILE_BYTES:
            raise ValueError(f"{path}: {size} bytes is too large for a scene file "
                             f"(at most {MAX_SCENE_FILE_BYTES})")
        with open(path, "rb") as f:
            raw = f.read(MAX_SCENE_FILE_BYTES + 1)
    except OSError as exc:
        raise ValueError(f"{path}: cannot read: {exc.strerror or exc}") from exc
    if len(raw) > MAX_SCENE_FILE_BYTES:  # grew, or a special file whose size says nothing
        raise ValueError(f"{path}: too large for a scene file (at most {MAX_SCENE_FILE_BYTES} bytes)")
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not a scene file: not UTF-8 text "
                         f"(byte 0x{raw[exc.start]:02x} at offset {exc.start})") from None


def read_scene_dict(path: Path) -> dict:
    """Parse a scene YAML file into a dict (``ValueError`` on an unreadable file, a syntax
    error or a document that is not a mapping)."""
    return _parse_scene_text(read_scene_text(path), path)


def _parse_scene_text(text: str, path: Path) -> dict:
    # aliases and duplicate keys are refused while parsing, before any value is looked at
    data = load_yaml(text, str(path))
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a scene must be a YAML mapping, got {type(data).__name__}")
    return data


def load_scene(name_or_path: str, trajectory=None, *, seed: int | None = None,
               **trajectory_options) -> SceneSpec:
    """Load and validate a scene by shipped name (``"ship"``) or by file path.

    A ``motion: {type: trajectory}`` has its pose file read (relative to the scene file) and
    fitted; ``trajectory`` (a path) puts that pose file under any scene instead, with
    ``trajectory_options`` (:func:`~gyro_attitude.io.trajectory_file.resolve_trajectory`).
    ``seed`` (given on a command line) replaces the file's ``seed:``, which may then be left
    out. Raises ``ValueError`` naming the bad key (``earth.latitude_deg: ...``) prefixed by
    the file.
    """
    from gyro_attitude.io.trajectory_file import resolve_trajectory

    path = find_scene_file(str(name_or_path))
    spec = validate_scene_text(read_scene_text(path), path, seed=seed)
    return resolve_trajectory(spec, path.parent, trajectory, **trajectory_options)


#: Kalibr imu.yaml keys -> (scene section, error key); the values are SI numbers.
KALIBR_TO_SCENE = {
    "gyroscope_noise_density": ("gyro", "arw"),
    "gyroscope_random_walk": ("gyro", "rate_random_walk"),
    "accelerometer_noise_density": ("accelerometer", "vrw"),
    "accelerometer_random_walk": ("accelerometer", "acceleration_random_walk"),
}
# scene error keys that set the same term as a Kalibr key (they must not both be given)
_SAME_TERM = {"arw": ("arw", "arw_rad_sqrt_s"), "vrw": ("vrw", "vrw_m_s_sqrt_s"),
              "rate_random_walk": ("rate_random_walk",),
              "acceleration_random_walk": ("acceleration_random_walk",)}


def merge_kalibr_imu(data: dict, path: Path) -> dict:
    """``data`` with its ``kalibr_imu: FILE`` (relative to the scene file) read into the
    gyro's (and, when the scene has one, the accelerometer's) error terms: white noise
    densities as ``arw`` / ``vrw``, bias random walks as ``rate_random_walk`` /
    ``acceleration_random_walk`` (continuous time, SI: the same convention as Kalibr)."""
    if "kalibr_imu" not in data:
        return data
    ref = data["kalibr_imu"]
    if not isinstance(ref, str) or not ref.strip():
        raise ValueError(f"kalibr_imu: must be the path of a Kalibr imu.yaml, got {ref!r:.80}")
    file = Path(ref) if Path(ref).is_absolute() else Path(path).parent / ref
    if not file.is_file():
        raise ValueError(f"kalibr_imu: {file}: no such file")
    kalibr = _parse_scene_text(read_scene_text(file), file)
    out = {k: v for k, v in data.items() if k != "kalibr_imu"}
    for key, (section, term) in KALIBR_TO_SCENE.items():
        if section == "accelerometer" and "accelerometer" not in data:
            continue
        if key not in kalibr:
            raise ValueError(f"kalibr_imu: {file.name}: {key} is missing")
        v = kalibr[key]
        if isinstance(v, bool) or not isinstance(v, int | float) or not (v >= 0 and v < 1e3):
            raise ValueError(f"kalibr_imu: {file.name}: {key} must be a number >= 0, got {v!r:.40}")
        block = dict(out.get(section) or {})
        errors = dict(block.get("errors") or {})
        clash = [k for k in _SAME_TERM[term] if k in errors]
        if clash:
            raise ValueError(f"{section}.errors.{clash[0]}: given by the scene and by "
                             f"kalibr_imu ({key}); keep one")
        errors[term] = float(v)
        block["errors"] = errors
        out[section] = block
    return out


def validate_scene_text(text: str, path: Path, seed: int | None = None) -> SceneSpec:
    """The validated scene of a file's ``text`` (``seed``: see :func:`load_scene`); errors
    are prefixed by the file's name."""
    path = Path(path)
    data = _parse_scene_text(text, path)
    if seed is not None:
        data = {**data, "seed": seed}
    try:
        return SceneSpec.from_dict(merge_kalibr_imu(data, path), name=path.stem)
    except ValueError as exc:
        raise ValueError(f"{path.name}: {exc}") from exc


def list_scenes() -> list[tuple[str, str]]:
    """``(name, description)`` of every shipped scene, sorted by name (first directory wins).

    The description is read from the file without validating the whole scene; a file that
    does not parse is listed with its error as description.
    """
    found: dict[str, str] = {}
    for d in scene_directories():
        for f in sorted(d.glob("*.yaml")):
            if f.stem in found:
                continue
            try:
                desc = str(read_scene_dict(f).get("description", "")).strip()
            except ValueError as exc:
                desc = f"(invalid: {exc})"
            found[f.stem] = desc.splitlines()[0] if desc else ""
    return sorted(found.items())
