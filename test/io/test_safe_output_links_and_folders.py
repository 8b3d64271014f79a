"""SafeOutput / check_output_path: hard links,
unwritable directories, the hidden partial folder, and forced replacement of a directory."""

import os

import pytest

from gyro_attitude.io import safe_output
from gyro_attitude.io.safe_output import OutputPathError, SafeOutput, check_output_path


def test_hard_link_to_the_input_is_refused(tmp_path):
    # A hard link has its own real path, so only the same-file check can see the input.
    inp = tmp_path / "in.mcap"
    inp.write_bytes(b"data")
    out = tmp_path / "out.mcap"
    os.link(inp, out)
    with pytest.raises(OutputPathError, match="is the input"):
        check_output_path(out, inputs=[inp], force=True)


def test_unwritable_directory_is_named(tmp_path, monkeypatch):
    # Tests may run as root, which ignores permission bits: stand in for a read-only
    # directory by answering "no" to any question about writing.
    monkeypatch.setattr(safe_output.os, "access", lambda path, mode: not mode & os.W_OK)
    with pytest.raises(OutputPathError, match=r"^output directory .* is not writable$"):
        check_output_path(tmp_path / "a.mcap")


def test_messages_name_the_output_by_default(tmp_path):
    (tmp_path / "a.mcap").write_bytes(b"")
    with pytest.raises(OutputPathError, match=r"^output .*a\.mcap exists"):
        check_output_path(tmp_path / "a.mcap")


def test_partial_output_lives_in_a_hidden_partial_folder(tmp_path):
    out = tmp_path / "run.mcap"
    s = SafeOutput(out)
    temp = s.open()
    folder = temp.parent
    assert folder.parent == tmp_path and temp.name == "run.mcap"
    assert folder.name.startswith(".run.mcap.") and folder.name.endswith(".partial")
    s.discard()
    assert list(tmp_path.iterdir()) == []


def test_forced_commit_replaces_an_existing_directory(tmp_path):
    out = tmp_path / "bag"
    out.mkdir()
    (out / "old.mcap").write_bytes(b"old")
    with SafeOutput(out, force=True) as temp:
        temp.mkdir()
        (temp / "bag_0.mcap").write_bytes(b"new")
    assert sorted(p.name for p in out.iterdir()) == ["bag_0.mcap"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bag"]
