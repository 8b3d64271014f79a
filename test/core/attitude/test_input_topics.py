"""The one-topic-per-input rule."""

from gyro_attitude.core.attitude.input_topics import shared_topic


def test_the_first_topic_named_twice_is_found_with_both_roles():
    assert shared_topic([("imu", "a"), ("truth", "b"), ("mag", "c")]) is None
    assert shared_topic([("imu", "a"), ("truth", "b"), ("odom", "c"), ("mag", "b")]) == (
        "mag", "truth", "b")
    assert shared_topic([]) is None
