"""replay --world-frame: the written orientation is the ENU one expressed in NED or NWU (the body
unchanged), with the world frame's name as frame_id."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from gyro_attitude.cli import main as cli_main
from gyro_attitude.io.imu_fast import read_imu_arrays, read_quaternion_stamped_arrays
from gyro_attitude.offline.simulate import simulate

# ENU -> world coordinates (rows: the world axes in ENU)
ENU_TO = {"ned": np.array([[0, 1, 0], [1, 0, 0], [0, 0, -1.0]]),
          "nwu": np.array([[0, 1, 0], [-1, 0, 0], [0, 0, 1.0]])}


@pytest.mark.parametrize("world", ["ned", "nwu"])
def test_world_frame_rotates_the_reference_not_the_body(tmp_path, world):
    rec = tmp_path / "in.mcap"
    simulate("handheld_mems", 8.0, rec)
    outs = {}
    for w in ("enu", world):
        out = tmp_path / f"{w}.mcap"
        assert cli_main(["replay", str(rec), "--out", str(out), "--frame", "enu",
                         "--latitude-deg", "52.5", "--world-frame", w]) == 0
        outs[w] = (read_quaternion_stamped_arrays(out, "attitude"),
                   read_imu_arrays(out, "imu/data"))
    (att_enu, _), (att_w, imu_w) = outs["enu"], outs[world]
    assert att_enu.frame_id == "enu" and att_w.frame_id == world
    expect = ENU_TO[world] @ Rotation.from_quat(att_enu.quaternion).as_matrix()
    np.testing.assert_allclose(Rotation.from_quat(att_w.quaternion).as_matrix(), expect,
                               atol=1e-12)
    np.testing.assert_allclose(imu_w.orientation, att_w.quaternion, atol=0)
