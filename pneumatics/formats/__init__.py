"""Recording file formats besides CSV (DESIGN.md "Recordings", docs/recordings.md).

* :mod:`.parquet` — the recording's table as Parquet (pyarrow), the sidecar metadata in the
  Parquet schema metadata; read with the CSV reader's checks.
* :mod:`.rosbag_map` — the ``[ros]`` section of an import map: which topic and field gives
  which recording column.
* :mod:`.rosbag` — ROS 1 bags, ROS 2 bags (sqlite3 and MCAP) read through such a map and
  resampled onto one time base (:mod:`rosbags`, no ROS install needed).
* :mod:`.by_suffix` — :func:`~.by_suffix.read_recording` / :func:`~.by_suffix.write_recording`:
  any of these by the file's suffix.

This package's ``__init__`` imports nothing: :mod:`pneumatics.recording` uses
:mod:`.parquet`, and the ROS readers build on :mod:`pneumatics.recording`.
"""
