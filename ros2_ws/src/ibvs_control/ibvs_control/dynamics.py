"""
M(q) and h(q, qdot) of the nominal robot, eq. (23)-(25), from PyBullet (no ROS).

The joint controller linearises the arm by u = M(q) v + h(q, qdot) (eq. 26). Its model is
the nominal robot's URDF (``ibvs_model.urdf.write_urdf(path, IRB4600, with_tool=True)``:
the same file the simulator loads for the nominal robot) in a PyBullet DIRECT client of its
own, so that it shares no state with the simulator's world:

- M(q) = calculateMassMatrix(q) (eq. 24; D(q) + J with the rotor inertia J folded into the
  links, which the URDF estimates; ABB publishes none),
- h(q, qdot) = calculateInverseDynamics(q, qdot, 0) = C(q, qdot) qdot + g(q) (eq. 25; the
  URDF has zero joint damping and friction, so B = 0),

both on the flat lists of the six movable joints (the tool and its markers hang on fixed
joints). Torque limits are the URDF's joint ``effort`` (ibvs_model.mass_model.joint_efforts).
"""

from pathlib import Path
import tempfile
from typing import TYPE_CHECKING

from ibvs_common.process import quiet_output
from ibvs_model import IRB4600
from ibvs_model.urdf import write_urdf
import numpy as np
from numpy.typing import ArrayLike, NDArray

if TYPE_CHECKING:
    from ibvs_model.robot import RobotParams

with quiet_output():  # PyBullet writes its build time as it loads
    import pybullet


class RobotDynamics:
    """M(q), h(q, qdot) and the torque limits of the robot, in a private DIRECT client."""

    def __init__(self, params: 'RobotParams' = IRB4600, with_tool: bool = True,
                 urdf_path: str | Path | None = None, gravity: float = 9.81) -> None:
        """Write the URDF of ``params`` (unless ``urdf_path`` is given) and load it."""
        self._tmp = None
        if urdf_path is None:
            self._tmp = tempfile.TemporaryDirectory(prefix='ibvs_control_')
            urdf_path = write_urdf(Path(self._tmp.name) / 'irb4600.urdf', params, with_tool)
        self.client = pybullet.connect(pybullet.DIRECT)
        try:
            self.body = pybullet.loadURDF(str(urdf_path), useFixedBase=True,
                                          flags=pybullet.URDF_USE_INERTIA_FROM_FILE,
                                          physicsClientId=self.client)
            pybullet.setGravity(0.0, 0.0, -gravity, physicsClientId=self.client)
            count = pybullet.getNumJoints(self.body, physicsClientId=self.client)
            joints = [pybullet.getJointInfo(self.body, j, physicsClientId=self.client)
                      for j in range(count)]
        except Exception:
            self.close()
            raise
        movable = [info for info in joints if info[2] != pybullet.JOINT_FIXED]
        self.joint_names = tuple(info[1].decode() for info in movable)
        if len(movable) != 6:
            self.close()
            raise ValueError(f'expected 6 movable joints in {urdf_path}, got '
                             f'{list(self.joint_names)}')
        self.torque_limits = np.array([info[10] for info in movable], dtype=float)
        self.speed_limits = np.array([info[11] for info in movable], dtype=float)
        self._zeros = [0.0] * 6

    def mass_matrix(self, q: ArrayLike) -> NDArray[np.float64]:
        """Return M(q) (6, 6), eq. (24)."""
        return np.array(pybullet.calculateMassMatrix(
            self.body, [float(v) for v in q], physicsClientId=self.client))

    def bias(self, q: ArrayLike, qdot: ArrayLike) -> NDArray[np.float64]:
        """Return h(q, qdot) = C(q, qdot) qdot + g(q) (6,), eq. (25)."""
        return np.array(pybullet.calculateInverseDynamics(
            self.body, [float(v) for v in q], [float(v) for v in qdot], self._zeros,
            physicsClientId=self.client))

    def close(self) -> None:
        """Disconnect the client and remove the temporary URDF."""
        if self.client is not None and self.client >= 0:
            try:
                pybullet.disconnect(physicsClientId=self.client)
            except pybullet.error:
                pass
        self.client = None
        if self._tmp is not None:
            self._tmp.cleanup()
            self._tmp = None
