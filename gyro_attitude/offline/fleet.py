"""Fleet replay: many recordings through :func:`~gyro_attitude.offline.replay.replay_file`, one
output each in a directory, on the Monte Carlo engine's runner (:mod:`.parallel`: a local
process pool or a Dask cluster).

:func:`fleet_pairs` expands the inputs (a pattern with ``*``, ``?`` or ``[`` is a glob, for a
shell that did not expand it) and names each output ``DIR/<input name without .mcap>.mcap``;
two inputs that would write the same output, or an output that is an input, are refused before
any work (the directory is created).  :func:`replay_fleet` replays each file in its own task: a
file that fails is reported with its one-line error, the others finish.
"""

from __future__ import annotations

import glob
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

from gyro_attitude.io.safe_output import check_output_path
from gyro_attitude.offline.parallel import CONNECT_TIMEOUT_S, run_tasks

__all__ = ["FleetFile", "fleet_pairs", "replay_fleet"]

_GLOB_CHARS = set("*?[")
#: what a replay imports where it uses it, preloaded once for a pool's workers: the offline
#: estimator's zero-phase filter
TASK_IMPORTS = ("scipy.signal",)


@dataclass
class FleetFile:
    """One input of a fleet replay: its output and the replay summary, or the error."""

    input: str
    output: str
    summary: dict | None = None
    error: str | None = None


def fleet_pairs(inputs, out_dir, *, force: bool = False) -> list[tuple[str, str]]:
    """``[(input, output)]`` in the order given (globs expanded and sorted); ValueError for a
    pattern that matches nothing, a missing input, two inputs with one output name, or an
    output that exists (without ``force``) or is an input."""
    files: list[str] = []
    for text in inputs:
        text = os.fspath(text)
        if _GLOB_CHARS & set(text) and not os.path.exists(text):
            matched = sorted(glob.glob(text))
            if not matched:
                raise ValueError(f"{text}: the pattern matches no file")
            files.extend(matched)
        else:
            if not os.path.exists(text):
                raise ValueError(f"{text}: no such file or bag directory")
            _check_bag(text)
            files.append(text)
    seen: dict[str, str] = {}
    out_dir = Path(out_dir)
    if out_dir.exists() and not out_dir.is_dir():
        raise ValueError(f"--out-dir {out_dir}: not a directory")
    pairs = []
    for f in dict.fromkeys(files):  # the same file named twice is replayed once
        name = Path(f).name
        stem = name[:-5] if name.endswith(".mcap") else name
        out = str(out_dir / f"{stem}.mcap")
        if out in seen:
            raise ValueError(f"{seen[out]} and {f} would both be written to {out}; "
                             "rename one or replay them into different directories")
        seen[out] = f
        pairs.append((f, out))
    out_dir.mkdir(parents=True, exist_ok=True)
    for _, out in pairs:
        check_output_path(out, inputs=files, force=force)
    return pairs


def separate_recordings_hint(exc) -> str:
    """What to give for a directory of separate recordings (``exc`` an
    :class:`~gyro_attitude.io.mcap_reader.UnorderedBagError`): each of its files."""
    pattern = glob.escape(os.fspath(exc.directory)) + "/*.mcap"
    return (f"; separate recordings: replay each with gyro-attitude replay '{pattern}' "
            "--out-dir OUT_DIR")


def _check_bag(path: str) -> None:
    """A directory input is one bag: several .mcap files without metadata.yaml are refused
    before any work, saying how to replay them as separate recordings."""
    if not os.path.isdir(path):
        return
    from gyro_attitude.io.mcap_reader import UnorderedBagError, bag_files

    try:
        bag_files(path)
    except UnorderedBagError as exc:
        raise ValueError(f"{exc}{separate_recordings_hint(exc)}") from None
    except ValueError:
        return  # the replay of that input reports it, with the others'


def _replay_task(task) -> dict:
    """Worker entry: one file; its summary, or ``{"error": one line}``."""
    from gyro_attitude.offline.replay import replay_file  # imported in the worker

    input_path, output_path, kwargs = task
    try:
        return {"summary": replay_file(input_path, output_path, **kwargs).summary()}
    except Exception as exc:  # reported per file: one bad recording must not stop the fleet
        text = str(exc).strip().splitlines()
        kind = "" if isinstance(exc, ValueError | OSError) else f"{type(exc).__name__}: "
        return {"error": kind + (text[0] if text else type(exc).__name__)}


def replay_fleet(pairs, *, workers: int = 1, scheduler: str | None = None,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S, on_file=None,
                 **replay_kwargs) -> tuple[list[FleetFile], bool]:
    """Replay every ``(input, output)`` pair with ``replay_kwargs`` (those of
    :func:`~gyro_attitude.offline.replay.replay_file`); ``on_file(FleetFile)`` as each
    finishes.  Returns the files in the order given and whether a Ctrl-C stopped the set
    (then the unfinished files have neither summary nor error)."""
    files = [FleetFile(i, o) for i, o in pairs]
    tasks = [(i, o, replay_kwargs) for i, o in pairs]

    def on_result(k, value):
        f = files[k]
        f.summary, f.error = value.get("summary"), value.get("error")
        if on_file is not None:
            on_file(f)

    def on_error(k, message):
        files[k].error = message
        if on_file is not None:
            on_file(files[k])

    try:
        run_tasks(_replay_task, tasks, on_result, workers=workers, scheduler=scheduler,
                  on_error=on_error, connect_timeout_s=connect_timeout_s,
                  preload=TASK_IMPORTS)
    except KeyboardInterrupt:
        _remove_partial_outputs([f for f in files if f.summary is None and f.error is None])
        return files, True
    return files, False


def _remove_partial_outputs(unfinished: list[FleetFile]) -> None:
    """The hidden temporary folders (``safe_output``) of outputs whose worker was stopped
    before its own clean-up ran: the stop happens once every worker has ended, so what is
    left under those names is this set's."""
    for f in unfinished:
        out = Path(f.output)
        for tmp in out.parent.glob(f".{glob.escape(out.name)}.*.partial"):
            shutil.rmtree(tmp, ignore_errors=True)
