"""check_output_path / SafeOutput: the requested name holds a finished output or what it
held before, never a partial one."""

import os

import pytest

from gyro_attitude.io.safe_output import OutputPathError, SafeOutput, check_output_path


def test_existing_output_refused_unless_forced_and_never_an_input(tmp_path):
    out = tmp_path / "a.mcap"
    assert check_output_path(out) == out
    out.write_bytes(b"old")
    with pytest.raises(ValueError, match="exists"):
        check_output_path(out)
    assert check_output_path(out, force=True) == out
    with pytest.raises(ValueError, match="is the input"):
        check_output_path(out, inputs=[tmp_path / "." / "a.mcap"], force=True)
    (tmp_path / "file").write_bytes(b"")
    with pytest.raises(ValueError, match="does not exist"):
        check_output_path(tmp_path / "file" / "x.mcap")
    for bad in ("", None, 5):
        with pytest.raises(ValueError, match="non-empty path"):
            check_output_path(bad)


def test_atomic_output_renames_on_success_and_keeps_the_old_file_on_failure(tmp_path):
    out = tmp_path / "a.mcap"
    out.write_bytes(b"old")
    with pytest.raises(RuntimeError), SafeOutput(out, force=True) as temp:
        temp.write_bytes(b"partial")
        assert temp.parent.parent == tmp_path and temp.name == out.name
        assert out.read_bytes() == b"old"
        raise RuntimeError("writer failed")
    assert out.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap"]  # temporary removed
    with SafeOutput(out, force=True) as temp:
        temp.write_bytes(b"new")
        assert out.read_bytes() == b"old"
    assert out.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap"]


def test_atomic_output_does_not_clobber_a_file_that_appeared_meanwhile(tmp_path):
    out = tmp_path / "a.mcap"
    atomic = SafeOutput(out)
    temp = atomic.open()
    temp.write_bytes(b"mine")
    out.write_bytes(b"someone else's")
    with pytest.raises(ValueError, match="appeared meanwhile"):
        atomic.commit()
    assert out.read_bytes() == b"someone else's" and temp.read_bytes() == b"mine"


def test_atomic_output_of_a_directory_keeps_inner_names(tmp_path):
    out = tmp_path / "bag"
    with SafeOutput(out) as temp:
        temp.mkdir()
        (temp / f"{temp.name}_0.mcap").write_bytes(b"x")  # a bag names its file after itself
    assert (out / "bag_0.mcap").read_bytes() == b"x"
# The input is never the output (directly, through a symlink, a relative path or its bag
# directory), an existing file needs force, and a failed write leaves nothing under the name.


@pytest.fixture()
def files(tmp_path):
    src = tmp_path / "in.mcap"
    src.write_bytes(b"input bytes")
    bag = tmp_path / "bag"
    bag.mkdir()
    (bag / "bag_0.mcap").write_bytes(b"bag bytes")
    link = tmp_path / "link.mcap"
    link.symlink_to(src)
    return tmp_path, src, bag, link


def test_output_resolving_to_the_input_is_refused_even_with_force(files):
    tmp, src, bag, link = files
    rel = os.path.relpath(src, os.getcwd())
    for out, inp in [(src, src), (link, src), (src, link), (rel, src),
                     (tmp / "sub" / ".." / "in.mcap", src), (bag / "bag_0.mcap", bag)]:
        if not (tmp / "sub").exists():
            (tmp / "sub").mkdir()
        with pytest.raises(OutputPathError, match="is the input"):
            check_output_path(out, inputs=[inp], force=True)
    assert src.read_bytes() == b"input bytes"


def test_existing_output_needs_force_and_bad_places_are_named(files):
    tmp, src, _, _ = files
    other = tmp / "other.mcap"
    other.write_bytes(b"x")
    with pytest.raises(OutputPathError, match="exists .use --force"):
        check_output_path(other, inputs=[src])
    assert check_output_path(other, inputs=[src], force=True) == other
    assert check_output_path(tmp / "new.mcap", inputs=[src]) == tmp / "new.mcap"
    with pytest.raises(OutputPathError, match="is a directory"):
        check_output_path(tmp, inputs=[src], force=True)
    with pytest.raises(OutputPathError, match="does not exist"):
        check_output_path(tmp / "missing" / "o.mcap", inputs=[src])
    ro = tmp / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        if not os.access(ro, os.W_OK):  # root can write anywhere: then nothing to check
            with pytest.raises(OutputPathError, match="not writable"):
                check_output_path(ro / "o.mcap", inputs=[src])
    finally:
        ro.chmod(0o700)


def test_commit_on_success_nothing_on_failure(tmp_path):
    out = tmp_path / "o.bin"
    out.write_bytes(b"old")
    with pytest.raises(RuntimeError):
        with SafeOutput(out) as tmp:
            tmp.write_bytes(b"half")
            raise RuntimeError("boom")
    assert out.read_bytes() == b"old" and sorted(p.name for p in tmp_path.iterdir()) == ["o.bin"]
    with pytest.raises(KeyboardInterrupt):
        with SafeOutput(tmp_path / "new.bin") as tmp:
            tmp.write_bytes(b"half")
            raise KeyboardInterrupt
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.bin"]
    with SafeOutput(out, force=True) as tmp:
        assert tmp.parent.parent == out.parent and tmp != out
        tmp.write_bytes(b"new")
        assert out.read_bytes() == b"old"  # replaced only at the end
    assert out.read_bytes() == b"new" and sorted(p.name for p in tmp_path.iterdir()) == ["o.bin"]


@pytest.mark.parametrize("special", ["/dev/null", "fifo"])
def test_devices_and_fifos_are_never_replaced_even_with_force(tmp_path, special):
    """``--out /dev/null --force`` once replaced the device node with a regular file."""
    if special == "fifo":
        special = tmp_path / "pipe"
        os.mkfifo(special)
    with pytest.raises(OutputPathError, match="not a regular file"):
        check_output_path(special, force=True)
    if special != "/dev/null":
        assert os.path.exists(special) and not os.path.isfile(special)


def test_a_symlink_output_is_replaced_beside_the_link_not_at_its_target(tmp_path):
    target_dir = tmp_path / "elsewhere"
    target_dir.mkdir()
    target = target_dir / "t.mcap"
    target.write_bytes(b"target")
    link = tmp_path / "link.mcap"
    link.symlink_to(target)
    check_output_path(link, force=True)
    with SafeOutput(link, force=True) as tmp:
        assert tmp.parent.parent == tmp_path  # same directory (file system) as the name
        tmp.write_bytes(b"new")
    assert link.read_bytes() == b"new" and not link.is_symlink()
    assert target.read_bytes() == b"target"  # the link's target is left alone


@pytest.fixture
def stop_cleared():
    from gyro_attitude.io import safe_output

    yield safe_output
    safe_output.stop_handled()


def test_no_output_is_committed_while_a_stop_is_pending(tmp_path, stop_cleared):
    so = stop_cleared
    out = tmp_path / "o.bin"
    so.request_stop()
    with pytest.raises(KeyboardInterrupt), SafeOutput(out) as tmp:
        tmp.write_bytes(b"finished, but the user asked to stop")
    assert list(tmp_path.iterdir()) == []
    # the stop handled (a partial result written on purpose): outputs are committed again
    so.stop_handled()
    with SafeOutput(out) as tmp:
        tmp.write_bytes(b"partial")
    assert out.read_bytes() == b"partial"


def test_a_discarded_output_cannot_be_committed(tmp_path):
    safe = SafeOutput(tmp_path / "o.bin")
    safe.open().write_bytes(b"x")
    safe.discard()
    with pytest.raises(OutputPathError, match="discarded"):
        safe.commit()
    assert list(tmp_path.iterdir()) == []


def test_a_repeated_signal_does_not_undo_a_handled_stop(stop_cleared):
    """The command line's handler: the first signal requests the stop; a second one, after
    the command handled it (Monte Carlo writing its finished runs), must not request it
    again, or the partial output would be thrown away."""
    from gyro_attitude.cli import _Interrupt

    handler = _Interrupt()
    with pytest.raises(KeyboardInterrupt):
        handler._handle(2, None)
    assert stop_cleared.stop_requested()
    stop_cleared.stop_handled()
    handler._handle(2, None)  # ignored
    assert not stop_cleared.stop_requested()
