"""
ROS 2 plumbing shared by the IBVS nodes (no control or vision maths here).

- :mod:`.contract`: topic names, joint names, QoS profiles and the lockstep timing rule.
- :mod:`.timing`: that timing rule, the period of a rate and seconds <-> integer
  nanoseconds (:func:`.timing.seconds_to_ns`, :func:`.timing.ns_to_seconds`), without rclpy.
- :mod:`.sync`: the stamp-ordered buffers the nodes' lockstep rules are built from.
- :mod:`.params`: parameters declared with descriptors and validated at start.
- :mod:`.diagnostics`: rejected-input counting, logging once per reason, /diagnostics.
- :mod:`.conversions`: messages <-> numpy arrays and :mod:`ibvs_model` objects, a façade
  over one module per message family (:mod:`.msg_time`, :mod:`.msg_joints`,
  :mod:`.msg_trajectory`, :mod:`.msg_pose`, :mod:`.msg_camera`, :mod:`.msg_features`).
- :mod:`.node_main`: the ``main()`` shape of ros2/demos ``demo_nodes_py``.
"""
