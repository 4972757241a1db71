"""PyBullet simulator of the IRB 4600 with screwdriver and fiducials, seen by a ZED 2."""
