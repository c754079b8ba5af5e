"""What every stealth-nav node shares, so that the three node shells differ only in what they do.

- :mod:`stealth_node_kit.parameters`: a node's parameter table (default, description, range,
  read-only), declared in one call with ROS descriptors; the finiteness check rclpy lacks.
- :mod:`stealth_node_kit.running`: the Jazzy ``main()`` (init, build, spin, shut down) with one
  error policy: bad arguments or a node that cannot start give one fatal line and exit code 2.
- :mod:`stealth_node_kit.full_disk`: a full disk in one line (the file, the space left) and the
  exit code EXIT_DISK_FULL that stops a node and its run instead of restarting it.
- :mod:`stealth_node_kit.endpoints`: QoS event callbacks kept to what can fire.
- :mod:`stealth_node_kit.conversions`: seconds to and from ``builtin_interfaces/Time``, yaw to
  and from a quaternion.
- :mod:`stealth_node_kit.log_throttle`: a log line that may repeat at every message, at most once
  per period.
"""
