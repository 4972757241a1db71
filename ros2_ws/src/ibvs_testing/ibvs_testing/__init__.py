"""
Test-only helpers of the IBVS packages; imports no IBVS package (the bottom of the tests).

- :mod:`.isolation`: each test process on its own ROS domain, on localhost (called
  explicitly, from the repository's root ``conftest.py``);
- :mod:`.fixtures`: pytest fixtures of private rclpy contexts and executors, and
  :func:`.fixtures.spin_until`;
- :mod:`.proc_tools`: process inspection through /proc;
- :mod:`.plain`: arrival orders and rclpy-free runs for tests of plain code.
"""
