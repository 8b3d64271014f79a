"""The one-topic-per-input rule."""

from gyro_attitude.core.attitude.input_topics import input_on_output, shared_topic


def test_the_first_topic_named_twice_is_found_with_both_roles():
    assert shared_topic([("imu", "a"), ("truth", "b"), ("mag", "c")]) is None
    assert shared_topic([("imu", "a"), ("truth", "b"), ("odom", "c"), ("mag", "b")]) == (
        "mag", "truth", "b")
    assert shared_topic([]) is None


def test_an_input_on_an_output_of_the_node_is_found():
    outputs = [("imu/data", "/imu/data"), ("attitude", "/attitude")]
    assert input_on_output([("imu", "/imu/data_raw"), ("mag", "/imu/mag")], outputs) is None
    assert input_on_output([("imu", "/imu/data_raw"), ("mag", "/imu/data")], outputs) == (
        "mag", "imu/data", "/imu/data")
    assert input_on_output([("imu", "/attitude")], outputs) == ("imu", "attitude", "/attitude")
    assert input_on_output([], outputs) is None
