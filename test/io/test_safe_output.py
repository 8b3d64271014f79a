"""check_output_path / AtomicOutput: the requested name holds a finished output or what it
held before, never a partial one."""

import pytest

from gyro_attitude.io.safe_output import AtomicOutput, check_output_path


def test_existing_output_refused_unless_forced_and_never_an_input(tmp_path):
    out = tmp_path / "a.mcap"
    assert check_output_path(out) == out
    out.write_bytes(b"old")
    with pytest.raises(ValueError, match="exists"):
        check_output_path(out)
    assert check_output_path(out, force=True) == out
    with pytest.raises(ValueError, match="also an input"):
        check_output_path(out, inputs=[tmp_path / "." / "a.mcap"], force=True)
    (tmp_path / "file").write_bytes(b"")
    with pytest.raises(ValueError, match="not a directory"):
        check_output_path(tmp_path / "file" / "x.mcap")
    for bad in ("", None, 5):
        with pytest.raises(ValueError, match="non-empty path"):
            check_output_path(bad)


def test_atomic_output_renames_on_success_and_keeps_the_old_file_on_failure(tmp_path):
    out = tmp_path / "a.mcap"
    out.write_bytes(b"old")
    with pytest.raises(RuntimeError), AtomicOutput(out, force=True) as temp:
        temp.write_bytes(b"partial")
        assert temp.parent.parent == tmp_path and temp.name == out.name
        assert out.read_bytes() == b"old"
        raise RuntimeError("writer failed")
    assert out.read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap"]  # temporary removed
    with AtomicOutput(out, force=True) as temp:
        temp.write_bytes(b"new")
        assert out.read_bytes() == b"old"
    assert out.read_bytes() == b"new"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.mcap"]


def test_atomic_output_does_not_clobber_a_file_that_appeared_meanwhile(tmp_path):
    out = tmp_path / "a.mcap"
    atomic = AtomicOutput(out)
    temp = atomic.open()
    temp.write_bytes(b"mine")
    out.write_bytes(b"someone else's")
    with pytest.raises(ValueError, match="appeared meanwhile"):
        atomic.commit()
    assert out.read_bytes() == b"someone else's" and temp.read_bytes() == b"mine"


def test_atomic_output_of_a_directory_keeps_inner_names(tmp_path):
    out = tmp_path / "bag"
    with AtomicOutput(out) as temp:
        temp.mkdir()
        (temp / f"{temp.name}_0.mcap").write_bytes(b"x")  # a bag names its file after itself
    assert (out / "bag_0.mcap").read_bytes() == b"x"
