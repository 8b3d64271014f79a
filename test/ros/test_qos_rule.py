"""The one QoS adaptation rule of recorder and player (rosbag2's): reliable / transient-local
only if every offered profile is."""

import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

from gyro_attitude.io.qos import parse_qos_profiles, qos_profile, qos_profiles_yaml
from gyro_attitude.ros.qos import adapted_qos

R, BE = "reliable", "best_effort"
TL, V = "transient_local", "volatile"


@pytest.mark.parametrize("offered, reliability, durability", [
    ([], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),  # rosbag2's default
    ([(R, TL)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.TRANSIENT_LOCAL),
    ([(R, V), (R, V)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
    ([(R, TL), (BE, TL)], ReliabilityPolicy.BEST_EFFORT, DurabilityPolicy.TRANSIENT_LOCAL),
    ([(R, TL), (R, V)], ReliabilityPolicy.RELIABLE, DurabilityPolicy.VOLATILE),
])
def test_adaptation_rule(offered, reliability, durability):
    # the same profiles as the recorder builds them and as the player reads them back
    profiles = [qos_profile(reliability=r, durability=d) for r, d in offered]
    from_file = parse_qos_profiles(qos_profiles_yaml(profiles)) if profiles else []
    for ps in (profiles, from_file):
        q = adapted_qos(ps, 7)
        assert (q.reliability, q.durability) == (reliability, durability)
        assert q.history == HistoryPolicy.KEEP_LAST and q.depth == 7
