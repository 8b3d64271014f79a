"""File I/O: rosbag2-compatible MCAP, safe output files. No rclpy import at module top.

* :mod:`.mcap_records` — MCAP record framing: opcodes, record builders, body parsers (the
  ``mcap`` package's, for descriptive records);
* :mod:`.mcap_reader` — the one MCAP reader (any profile; damage-tolerant, hostile sizes and
  counts checked; file or log-time order);
* :mod:`.imu_fast` — :func:`~.imu_fast.read_imu_arrays` and friends: chunk-wide array
  decoding on top of the reader, with a per-message rclpy fallback;
* :mod:`.cdr_arrays` — the fixed CDR layouts (written once) and the array encoders
  (:class:`~.cdr_arrays.MessageBatch`);
* :mod:`.rosbag2_profile` — schemas, channel metadata, ``rosbag2`` metadata, bag directory;
* :mod:`.mcap_writer` — :class:`~.mcap_writer.Rosbag2McapWriter` (chunks, indexes, summary;
  message batches merged by log time);
* :mod:`.safe_output` — output checks (never the input, no silent overwrite) and atomic
  replacement through a temporary file;
* :mod:`.ros2_schema` — ``ros2msg`` schema text and type hashes from the installed share;
* :mod:`.qos` — ``offered_qos_profiles`` YAML;
* :mod:`.make_sample_bag` — regenerates ``bags/coning_200hz.mcap``;
* :mod:`.scene_file` — scene YAML loading.
"""
