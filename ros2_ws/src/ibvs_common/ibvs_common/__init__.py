"""
ROS 2 plumbing shared by the IBVS nodes (no control or vision maths here).

- :mod:`.contract`: topic names, joint names, QoS profiles and the lockstep timing rule.
- :mod:`.timing`: that timing rule and the period of a rate in nanoseconds, without rclpy.
- :mod:`.params`: parameters declared with descriptors and validated at start.
- :mod:`.diagnostics`: rejected-input counting, logging once per reason, /diagnostics.
- :mod:`.conversions`: messages <-> numpy arrays and :mod:`ibvs_model` objects.
- :mod:`.node_main`: the ``main()`` shape of ros2/demos ``demo_nodes_py``.
"""
