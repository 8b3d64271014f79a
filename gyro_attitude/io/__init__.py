"""File I/O: rosbag2-compatible MCAP. No rclpy import at module top.

* :mod:`.mcap_writer` — :class:`~.mcap_writer.Rosbag2McapWriter` (files as rosbag2 Jazzy
  writes them; array paths for Imu / QuaternionStamped);
* :mod:`.mcap_reader` — damage-tolerant streaming reader (no summary needed);
* :mod:`.imu_fast` — :func:`~.imu_fast.read_imu_arrays` and friends: chunk-wide array
  decoding with a per-message rclpy fallback;
* :mod:`.cdr_arrays` — the fixed CDR layouts as numpy structured dtypes;
* :mod:`.ros2_schema` — ``ros2msg`` schema text and type hashes from the installed share;
* :mod:`.qos` — ``offered_qos_profiles`` YAML;
* :mod:`.make_sample_bag` — regenerates ``bags/coning_200hz.mcap``;
* :mod:`.scene_file` — scene YAML loading (scenes team).
"""
